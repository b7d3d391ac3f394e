"""The simulated robot around the node, shared by the mock controller, the demo, the benchmark
and the stress test: the motion (:mod:`.trajectories`), the controller's DDS side
(:mod:`.controller`), pairing each pose with the input it answers (:mod:`.matching`), the node
as a child process (:mod:`.node_process`) and a stand-in that only echoes, the transport floor
(:mod:`.echo_node`)."""
