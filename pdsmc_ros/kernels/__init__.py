"""pdsmc_ros.kernels."""
