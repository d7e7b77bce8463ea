"""League of Robot Runners runs: schedulers, the run loop, the start kit output file."""
