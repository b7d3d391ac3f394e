"""The ``glpma_fk`` node: the transport-free service (parameters, validation, statistics, the solve and
assembly-modes loops) and its two thin transports, rclpy (:mod:`.ros_node`) and Cyclone DDS (:mod:`.dds`)."""
