"""The node's everyday input in one compiled call (``glpma_ros.node.pose_lane``, ``FkService.solve_message``,
``SolveLoop.offer_message``): a leg_lengths message's bytes give the pose, statistics and extra outputs the long way
gives, its pose's message reads back as that pose, and every message it does not take is left to the long way with
nothing changed."""
import math

import numpy as np
import pytest
import yaml

from conftest import GENEROUS_BUDGET_MS, HEX_YAML, RPR_YAML
from glpma_ros.node.dds import cdr
from glpma_ros.node.loops import SolveLoop
from glpma_ros.node.service import EncodedPose, FkService, PoseOutput
from glpma_ros.runtime.precompile import warm_up_legs
from glpma_tools.sim.controller import pose_stamped_fields

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]
BUDGET = {"time_budget_ms": GENEROUS_BUDGET_MS}
ENCODE = cdr.Encoder()
#: both ways run the same compiled arithmetic on the same doubles; a femtometre-scale bound (1e-12 of a metre)
#: still lets another CPU's kernels round differently between the two processes' compiled code paths
SAME_POSE_M = 1e-12


def message(values) -> bytes:
    return ENCODE.float64_multi_array(values)


def services(path=RPR_YAML, **params):
    """Two services warm at the seed pose: one fed messages, one fed the same floats."""
    values = {"manipulator_config": str(path), "initial_pose": SEED_X if path == RPR_YAML else [], **BUDGET, **params}
    return FkService(values), FkService(values)


def track(model, n=40, step=0.05):
    """Readings (metres) along a small motion from the seed pose."""
    xs = [np.array(SEED_X) + k * step * np.array([1.0, -0.7, 0.004]) for k in range(n)]
    return [tuple((model.inverse_kinematics(x) * model.metres_per_unit).tolist()) for x in xs]


def test_a_message_gives_the_pose_the_long_way_gives_and_its_bytes_read_back_as_it():
    lane, long_way = services(frame_id="robot_base")
    model = lane.model
    for k, readings in enumerate(track(model)):
        stamp = 1_700_000_000_123_456_789 + k * 1_000_000
        out = lane.solve_message(message(readings), stamp)
        assert out is not None and type(out.pose) is EncodedPose, k
        assert out.estimate is None                 # built after the write, by account
        stamp_read, frame, position, orientation = pose_stamped_fields(out.pose.message)
        lane.account(out)
        ref = long_way.handle(readings, stamp)
        assert type(out.pose) is PoseOutput and ref.pose is not None
        assert out.estimate.status == ref.estimate.status == "converged"
        assert out.estimate.start == "warm" and out.estimate.evaluations == ref.estimate.evaluations
        assert (stamp_read, frame) == (stamp, "robot_base") == (out.pose.stamp_ns, out.pose.frame_id)
        np.testing.assert_allclose(position, out.pose.position, rtol=0, atol=SAME_POSE_M)
        np.testing.assert_allclose(orientation, out.pose.orientation, rtol=0, atol=SAME_POSE_M)
        np.testing.assert_allclose(out.pose.position, ref.pose.position, rtol=0, atol=SAME_POSE_M)
        np.testing.assert_allclose(out.pose.orientation, ref.pose.orientation, rtol=0, atol=SAME_POSE_M)
        np.testing.assert_allclose(out.legs, ref.legs, rtol=0, atol=SAME_POSE_M / model.metres_per_unit)
        np.testing.assert_allclose(lane.estimator.warm_x, long_way.estimator.warm_x, rtol=0, atol=1e-9)
    a, b = lane.stats.snapshot(), long_way.stats.snapshot()
    assert a.handled == b.handled == 40 and a.published == b.published == 40


def test_the_extra_outputs_of_a_message_s_pose_are_the_long_way_s():
    lane, long_way = services()
    for readings in track(lane.model, n=5):
        out = lane.solve_message(message(readings), 7)
        lane.account(out)
        ref = long_way.handle(readings, 7)
        mine, theirs = lane.extras(out), long_way.extras(ref)
        assert mine.stamp_ns == theirs.stamp_ns and mine.child_frame_id == theirs.child_frame_id
        np.testing.assert_allclose(mine.position, theirs.position, rtol=0, atol=SAME_POSE_M)
        # the covariance propagates the leg noise through the Jacobian at (nearly) the same pose: relative 1e-9
        np.testing.assert_allclose(mine.covariance, theirs.covariance, rtol=1e-9, atol=1e-30)


@pytest.mark.parametrize("case", ["layout", "big_endian", "count", "nan", "band", "short", "bytearray"])
def test_a_message_the_kernel_does_not_take_changes_nothing(case):
    svc, _ = services()
    readings = track(svc.model, n=2)[1]
    data = {
        "layout": None,
        "big_endian": b"\x00\x00" + message(readings)[2:],
        "count": message(readings[:2]),
        "nan": message((readings[0], math.nan, readings[2])),
        "band": message((readings[0], readings[1] * 1000.0, readings[2])),    # millimetres sent as metres
        "short": message(readings)[:-8],
        "bytearray": bytearray(message(readings)),
    }[case]
    if case == "layout":
        pytest.importorskip("cyclonedds")
        from glpma_ros.node.dds import messages as M
        data = M.Float64MultiArray(M.MultiArrayLayout([M.MultiArrayDimension("legs", 3, 3)], 0),
                                   list(readings)).serialize()
    warm_x = svc.estimator.warm_x
    before = warm_x.copy()
    assert svc.solve_message(data, 0) is None
    assert svc.estimator.warm_x is warm_x
    np.testing.assert_array_equal(warm_x, before)       # untouched: the same array, the same values
    assert svc.stats.snapshot().handled == 0


def test_where_the_one_call_way_does_not_apply_it_declines():
    cold, _ = services(path=HEX_YAML)                       # no warm start yet
    legs = warm_up_legs(cold.model) * cold.model.metres_per_unit
    assert cold.solve_message(message(legs), 0) is None
    off, _ = services(polish=False)
    assert off.solve_message(message(track(off.model, 2)[1]), 0) is None


def test_a_warm_stage_the_rule_declines_goes_on_to_the_search_as_the_long_way():
    """Legs no pose reaches (inside the plausible band): the warm stage does not converge, the rule declines
    it, and the search decides what the long way decides, from the same work (a generous budget)."""
    lane, long_way = services()
    unreachable = (0.06, 0.06, 0.06)                # metres: the seed 3-RPR has no assembly there
    out = lane.solve_message(message(unreachable), 5)
    ref = long_way.solve(unreachable, 5)
    assert out is not None and out.warm is None and type(out.pose) is not EncodedPose
    assert out.pose is None and ref.pose is None
    assert out.reason == ref.reason and out.reason.startswith("no_solution"), out.reason
    assert lane.stats.snapshot().rejected == 1
    # the next message from the seed's legs is solved warm again from the same state as the long way's
    readings = track(lane.model, n=2)[1]
    again, ref = lane.solve_message(message(readings), 6), long_way.solve(readings, 6)
    assert type(again.pose) is EncodedPose
    lane.account(again)
    np.testing.assert_allclose(again.pose.position, ref.pose.position, rtol=0, atol=SAME_POSE_M)


def test_an_input_the_legs_cannot_be_is_rejected_with_its_reason_on_either_way():
    svc, _ = services()
    readings = track(svc.model, 2)[1]
    assert svc.solve_message(message((readings[0], -readings[1], readings[2])), 0) is None   # outside the band
    out = svc.solve((readings[0], -readings[1], readings[2]), 0)
    assert out.pose is None and "leg" in out.reason


def test_the_solve_loop_publishes_a_message_s_pose_and_keeps_it_as_the_last_input():
    svc, _ = services()
    poses = []
    loop = SolveLoop(svc, poses.append, stats=svc.stats, modes=svc.modes)
    track_m = track(svc.model, n=6)
    for k, readings in enumerate(track_m):
        assert loop.offer_message(message(readings), 1000 + k)
    assert [type(p) for p in poses] == [EncodedPose] * 6
    assert [pose_stamped_fields(p.message)[0] for p in poses] == [1000 + k for k in range(6)]
    assert svc.stats.snapshot().published == 6
    # the assembly modes are asked of the last input received: a message's bytes read back as its legs
    legs, stamp, _, _ = svc.modes.request_input()
    np.testing.assert_allclose(legs, np.asarray(track_m[-1]) / svc.model.metres_per_unit, rtol=1e-12)
    assert stamp == 1005
    # a message the kernel does not take: nothing done, nothing published (the transport decodes it)
    assert not loop.offer_message(message(track_m[0][:2]), 2000)
    assert len(poses) == 6
    loop.stop()


def test_a_solve_in_progress_leaves_a_message_to_the_long_way():
    """A message offered while another input is being solved (another reader thread: here, from inside the pose's
    publish) is not solved there: False, and the transport offers its decoded legs, which wait for that solve."""
    svc, _ = services()
    readings = track(svc.model, n=3)
    nested, stamps = [], []

    def publish(pose):
        stamps.append(pose_stamped_fields(pose.message)[0] if type(pose) is EncodedPose else pose.stamp_ns)
        if not nested:
            nested.append(loop.offer_message(message(readings[2]), 2))
            loop.offer(readings[2], 2)

    loop = SolveLoop(svc, publish, stats=svc.stats, modes=svc.modes)
    assert loop.offer_message(message(readings[1]), 1)
    assert nested == [False] and stamps == [1, 2]
    assert svc.stats.snapshot().published == 2
    loop.stop()


def test_a_config_s_leg_offsets_and_frame_reach_the_message_s_pose(tmp_path):
    doc = yaml.safe_load(RPR_YAML.read_text())
    offsets = [0.8, -0.5, 1.2]
    path = tmp_path / "offsets.yaml"
    path.write_text(yaml.safe_dump({**doc, "leg_offsets": offsets}))
    svc = FkService({"manipulator_config": str(path), "initial_pose": SEED_X, "frame_id": "a", **BUDGET})
    model = svc.model
    x = np.array(SEED_X) + np.array([0.3, -0.2, 0.001])
    readings = tuple(((model.inverse_kinematics(x) - offsets) * model.metres_per_unit).tolist())
    out = svc.solve_message(message(readings), 3)
    assert type(out.pose) is EncodedPose
    _, frame, position, _ = pose_stamped_fields(out.pose.message)
    # the legs solved to round-off: a micrometre bounds the pose with room to spare
    np.testing.assert_allclose(position, np.asarray(model.pose(x).position) * model.metres_per_unit, atol=1e-6)
    svc.account(out)
    assert svc.set_parameters({"frame_id": "b"}) == (True, "")
    out = svc.solve_message(message(readings), 4)
    assert pose_stamped_fields(out.pose.message)[1] == "b"
