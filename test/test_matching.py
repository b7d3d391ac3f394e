"""Pairing each pose of the node with the input it answers (glpma_ros.testing.matching), without a
node: inputs along the simulated loop, poses as a node would publish them."""
import numpy as np
import pytest

from glpma_ros.testing.matching import compare, pair
from glpma_tools.sim.controller import Sent
from glpma_tools.sim.trajectories import PERIOD_S, Plan, variables_along

RATE_HZ = 200.0
T0_NS = 1_700_000_000_000_000_000


@pytest.fixture(scope="module", params=["planar_3rpr_seed", "hexapod_66_rolland"])
def run(request):
    """Three loops of inputs at 200 Hz (the legs repeat every loop)."""
    plan = Plan(request.param)
    sent = []
    for i in range(int(3 * PERIOD_S * RATE_HZ)):
        legs, position_m, q = plan.sample(i / RATE_HZ)
        sent.append(Sent(T0_NS + i * 5_000_000, legs, position_m, q))
    return plan, sent


def pose_of(s, arrival_ns, receive_ns=None):
    """A pose as the listener records it: (received, stamp, frame_id, position m, quaternion)."""
    return (receive_ns or arrival_ns + 1_000_000, arrival_ns, "base", np.array(s.position_m), np.array(s.quaternion))


def test_the_loop_never_repeats_within_a_period(run):
    plan, sent = run
    n = int(PERIOD_S * RATE_HZ)
    legs = np.array([s.legs for s in sent[:n]])
    gaps = [np.max(np.abs(legs[k + 1:] - legs[k]), axis=1).min() for k in range(n - 1)]
    assert min(gaps) > 1e-6 * plan.model.scale
    assert np.allclose(sent[n].legs, sent[0].legs)           # and repeats a period later


def test_poses_pair_with_their_own_input_across_repeating_loops(run):
    plan, sent = run
    answered = list(range(0, len(sent), 3))
    poses = [pose_of(sent[i], sent[i].send_ns + 2_000_000) for i in answered]
    c = compare(plan.model, sent, poses)
    assert list(c.index) == answered and not c.unpaired
    assert c.position_error_m.max() == 0.0 and c.legs_residual_m.max() < 1e-12
    np.testing.assert_allclose(c.latency_ms, 3.0)


def test_a_pose_that_reproduces_no_input_or_answers_one_twice_pairs_with_nothing(run):
    plan, sent = run
    good = pose_of(sent[10], sent[10].send_ns + 1)
    moved = (good[0], good[1], "base", good[3] + 1e-4, good[4])          # 0.1 mm off: legs of no input
    garbage = (good[0], good[1], "base", np.full(3, np.nan), np.zeros(4))
    pairs, unpaired = pair(plan.model, sent, [good, good, moved, garbage])
    assert [i for i, _, _ in pairs] == [10] and len(unpaired) == 3


def test_clocks_that_disagree_pair_with_the_input_sent_nearest_the_stamp(run):
    plan, sent = run
    early = pose_of(sent[20], sent[20].send_ns - 1_000_000)             # the node's clock 1 ms behind
    pairs, unpaired = pair(plan.model, sent, [early])
    assert [i for i, _, _ in pairs] == [20] and not unpaired


def test_joint_state_poses_pair_by_stamp(run):
    plan, sent = run
    poses = [pose_of(sent[i], sent[i].send_ns) for i in (5, 6, 900)]
    wrong = pose_of(sent[7], sent[8].send_ns)                            # input 8's stamp, input 7's pose
    c = compare(plan.model, sent, poses + [wrong], by_stamp=True)
    assert list(c.index) == [5, 6, 8, 900] and not c.unpaired
    assert c.on_truth.tolist() == [True, True, False, True]             # the pose for input 8 is wrong


def test_the_tests_loop_starts_at_the_given_variables(run):
    plan, _ = run
    x0 = plan.start_variables()
    loop = variables_along(plan.model, x0, 100, amplitude=2.0)
    assert loop.shape == (100, plan.model.n_vars)
    assert plan.model.distance(loop[0], x0) < 1e-9 * plan.model.scale


def test_poses_that_carry_their_legs_pair_by_them_and_split_at_the_stamp(run):
    """The echo node's poses (legs instead of a pose), paired with ``legs_of``; the latency
    split at the stamp adds up to written -> received."""
    from glpma_ros.testing.matching import split_at_stamp
    plan, sent = run
    n = plan.model.n_legs

    def echoed(i, arrival_ns, late_ns):
        numbers = np.r_[sent[i].legs * plan.mpu, np.zeros(7 - n)]
        return (arrival_ns + late_ns, arrival_ns, "base", numbers[:3], numbers[3:])
    # input 11 arrives after input 12 was written (its stamp is later than 12's send time)
    poses = [echoed(10, sent[10].send_ns + 300_000, 200_000), echoed(11, sent[12].send_ns + 1, 100_000),
             echoed(900, sent[900].send_ns + 50_000, 70_000), echoed(900, sent[900].send_ns + 60_000, 0)]
    pairs, unpaired = pair(plan.model, sent, poses, legs_of=lambda p: np.r_[p[3], p[4]][:n] / plan.mpu)
    assert [i for i, _, _ in pairs] == [10, 11, 900] and len(unpaired) == 1    # one input, one pose
    to_node, in_node = split_at_stamp(sent, [i for i, _, _ in pairs], [p for _, p, _ in pairs])
    np.testing.assert_allclose(to_node, [0.3, 5.0 + 1e-6, 0.05])
    np.testing.assert_allclose(in_node, [0.2, 0.1, 0.07])
