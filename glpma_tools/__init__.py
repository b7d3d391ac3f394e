"""What developers and researchers run around the node: offline processing of recorded bags,
workspace maps, the simulated controller, the demo, the benchmark, the stress test and the simulation
helpers they share.  Not needed by ``ros2 run glpma_ros fk_node``; their dependencies are the extras
``tools``, ``bag``, ``map`` and ``bench`` (``pip install .[tools]``)."""
