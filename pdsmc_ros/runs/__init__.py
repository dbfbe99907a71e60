"""pdsmc_ros.runs."""
