"""Guide paths and fields for the PIBT family: lane guidance costs (``guidance``) and traffic-flow guide paths
with PIBT along them (``flow``)."""
