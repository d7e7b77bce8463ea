"""The League of Robot Runners: instances, the MAPF_T rules, the simulator and its envs."""
