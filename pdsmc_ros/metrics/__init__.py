"""pdsmc_ros.metrics."""
