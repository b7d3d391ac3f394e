"""What developers and researchers run around the node: the simulated controller, the demo, the benchmark,
the stress test and the simulation helpers they share.  Not needed by ``ros2 run glpma_ros fk_node``;
installed with the ``tools`` extra's dependencies (``pip install .[tools]``)."""
