"""Tools around the ``glpma_ros`` node: offline processing of recorded bags, workspace maps."""
