"""Command line of ``glpma-fk calibrate`` (:func:`main`): read CONFIG and DATA, hold out a share of
the measurements, identify (:func:`.identify.identify`), check the forward kinematics on the held-out
measurements (:func:`holdout_pose_errors`), report, write NEW.yaml (:mod:`.yaml_edit`)."""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

from ..cli.api import command_main, manipulator_parser, require, seed_type
from ..config import load_document, model_from_dict, resolve_config
from ..errors import InputError
from ..estimation.estimator import STATIONARY
from ..models.legs import REVOLUTE
from ..models.rotations import matrix_from_quaternion, quaternion_from_matrix
from ..solvers.local import LocalSolver
from . import data as D
from .identify import FIELD, GROUPS, SCALAR_GROUPS, WEAK_SE_SHARE, Measurements, identify, leg_residuals
from .parameters import NAMED_COMPONENT, PART, gauge_text, kind_groups
from .yaml_edit import check_edit, edit_config

PROG = "glpma-fk calibrate"
#: default share of the measurements held out of the fit to check it
HOLDOUT = 0.2
#: the fit needs at least this many measurements per parameter of a leg, so that the residual
#: variance behind the standard errors has as many degrees of freedom as there are parameters
MIN_MEASUREMENTS_PER_PARAMETER = 2
#: a leg residual RMS of the nominal geometry above this share of its size means the poses do not
#: belong to the legs (another unit, columns swapped, a pose base -> platform): 5 % is fifty times
#: the joint errors a calibration corrects
MISMATCH_SHARE = 0.05
#: YAML key of each identified group: top-level keys of a length-actuated config ...
KEYS = {"base": "base", "platform": "platform", "offsets": "leg_offsets"}
#: ... and of an actuated family's: the offsets top-level, the rest keys of each item of ``legs``
FAMILY_KEYS = {"origin": "origin", "crank": "crank", "axis": "axis", "rod": "rod", "platform": "platform",
               "offsets": "actuator_offsets"}
#: width of the --help texts
HELP_WIDTH = 100
#: iterations of each held-out forward-kinematics solve (the local solve's Levenberg-Marquardt, from
#: the measured pose: a few iterations reach the pose, the cap bounds the work whatever the data)
HOLDOUT_FK_MAX_ITER = 50


def build_parser() -> argparse.ArgumentParser:
    p = manipulator_parser(
        PROG, metavar="CONFIG", formatter_class=argparse.RawDescriptionHelpFormatter,
        usage=f"{PROG} CONFIG DATA --out NEW.yaml [--identify GROUP ...] [--holdout SHARE] "
              f"[--legs-topic T --pose-topic T --max-dt S] [--seed N] [--strict] [--json]",
        description=textwrap.fill(
            "Identify the manipulator's real geometry -- base joints, platform joints and the zero offsets of "
            "the leg sensors; for an actuated family (delta, linear_delta, rus_6, pus_6, planar_3rrr, planar_3prr) "
            "the legs' origins, cranks or rail directions, rods, platform joints and the actuators' zero offsets -- "
            "from sensor readings paired with externally measured platform poses (laser tracker, "
            "motion capture), by least squares on the legs' inverse-kinematic residuals "
            "|p + R B_i - P_i(q_i + offset_i)| - rod_i, and write NEW.yaml: CONFIG with the identified entries "
            "(CONFIG is never modified). Gauge directions of the leg model (a crank turned against its "
            "actuator's offset, a rail's origin moved along it against its offset, a Delta's origin and "
            "platform joint moved together) stay at nominal and are named. Parameter directions the data do not "
            "identify "
            "(standard error above 0.1 % of the manipulator's size, or not seen at all) stay at nominal and are "
            "named in warnings with the poses that would identify them (truncated SVD). Reports the leg residual "
            "RMS before and after, on the fitted and on held-out measurements, the forward kinematics' position "
            "and rotation error on the held-out measurements, each parameter with its standard error, the "
            "campaign's observability and the directions the data see badly. Exit 2 with one line for too few "
            "measurements or a malformed file, and with --strict for a direction left at nominal.", HELP_WIDTH,
            break_on_hyphens=False))
    p.add_argument("data", metavar="DATA",
                   help="CSV with a header row: leg_1 .. leg_n (sensor readings: leg lengths, config unit; actuator "
                        "positions, radians for revolute and config unit for prismatic actuators), then the measured "
                        "pose in the base frame, planar x y theta (radians), spatial x y z qx qy qz qw (unit "
                        "quaternion platform -> base), a Delta x y z; or a rosbag2 (directory, .mcap or .db3) in "
                        "metres and radians")
    p.add_argument("--out", required=True, metavar="NEW.yaml", help="the calibrated config to write")
    p.add_argument("--identify", nargs="+", choices=GROUPS, default=None, metavar="GROUP",
                   help="what to estimate (default all of the legs' groups); the rest stays as in CONFIG: "
                        "base platform offsets for length-actuated legs, origin crank rod platform offsets for "
                        "revolute and origin axis rod platform offsets for prismatic actuators")
    p.add_argument("--holdout", type=float, default=HOLDOUT, metavar="SHARE",
                   help=f"share of the measurements left out of the fit to check it, 0 <= SHARE < 1 "
                        f"(default {HOLDOUT:g})")
    p.add_argument("--legs-topic", default=None, metavar="T",
                   help="rosbag2: the leg readings (std_msgs/msg/Float64MultiArray or sensor_msgs/msg/JointState "
                        "with joints leg_1 .. leg_n, metres; default: the bag's only topic of these types)")
    p.add_argument("--pose-topic", default=None, metavar="T",
                   help="rosbag2: the reference geometry_msgs/msg/PoseStamped (metres; default: the bag's only one)")
    p.add_argument("--max-dt", type=float, default=None, metavar="S",
                   help=f"rosbag2: largest time between a pose and its leg reading, seconds (default {D.MAX_DT_S:g})")
    p.add_argument("--seed", type=seed_type, default=0, help="seed of the held-out choice (default 0)")
    p.add_argument("--strict", action="store_true",
                   help="refuse (exit 2, one line naming them, nothing written) when a parameter direction would be "
                        "left at nominal, instead of warning")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return p


@command_main(prog=PROG)
def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    report = run(args)
    print(json.dumps(report) if args.json else text(report))
    return 0


def _read(args, model, nominal) -> tuple:
    """The measurements of DATA and, for a bag, what it held."""
    path = Path(args.data)
    bag_options = [o for o, v in (("--legs-topic", args.legs_topic), ("--pose-topic", args.pose_topic),
                                  ("--max-dt", args.max_dt)) if v is not None]
    if not path.exists():
        raise InputError(f"DATA {path} does not exist")
    n, dim = model.base.shape
    actuated, translation = nominal.actuated, nominal.translation
    if D.is_bag(path):
        require("bag", PROG, modules=("rosbags",))
        max_dt = D.MAX_DT_S if args.max_dt is None else args.max_dt
        if not (math.isfinite(max_dt) and max_dt >= 0.0):
            raise InputError(f"--max-dt must be a non-negative number of seconds, got {max_dt:g}")
        from_si = (lambda v: np.array([model.readings_from_si(row) for row in v]).reshape(v.shape)) \
            if actuated else None
        return D.read_bag(path, n, dim, model.metres_per_unit, args.legs_topic, args.pose_topic, max_dt,
                          from_si, translation)
    if bag_options:
        raise InputError(f"{bag_options[0]} applies to a rosbag2; {path} is read as a CSV file")
    return D.read_csv(path, n, dim, model.unit, actuated, translation), None


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _rms(r) -> float | None:
    return float(np.sqrt(np.mean(np.square(r)))) if np.size(r) else None


def run(args) -> dict:
    t_start = time.perf_counter()
    if not (math.isfinite(args.holdout) and 0.0 <= args.holdout < 1.0):
        raise InputError(f"--holdout must be a share 0 <= SHARE < 1, got {args.holdout:g}")
    config_path = resolve_config(args.config)
    doc = load_document(config_path)
    model = model_from_dict(doc, str(config_path))
    nominal = D.geometry_of(model)
    own = kind_groups(nominal.kind)
    if args.identify is not None:
        foreign = [g for g in args.identify if g not in own]
        if foreign:
            raise InputError(f"--identify {foreign[0]}: the legs of {model.kind} have no {PART[foreign[0]]}; "
                             f"their groups are {' '.join(own)}")
    out = Path(args.out)
    for what, other in (("CONFIG", config_path), ("DATA", Path(args.data))):
        if _same_file(out, other) or out.resolve() == other.resolve():
            raise InputError(f"--out {out} is {what}; write the calibrated config to another file "
                             f"({what} is never modified)")
    meas, bag = _read(args, model, nominal)
    groups = tuple(g for g in own if args.identify is None or g in args.identify)
    n, dim = model.base.shape
    k = sum(1 if g in SCALAR_GROUPS else dim for g in groups)
    m = len(meas)
    held = int(round(args.holdout * m))
    order = np.random.default_rng(args.seed).permutation(m)
    fit_index, hold_index = np.sort(order[held:]), np.sort(order[:held])
    need = MIN_MEASUREMENTS_PER_PARAMETER * k
    if len(fit_index) < need:
        raise InputError(f"too few measurements: {len(fit_index)} to fit ({m} in {args.data}, {held} held out) for "
                         f"{k} parameters per leg; need at least {need}")
    fit, hold = meas.subset(fit_index), meas.subset(hold_index)
    before = leg_residuals(nominal, fit)
    rms_before = _rms(before)
    if rms_before > MISMATCH_SHARE * model.scale:
        raise InputError(f"the poses do not fit the legs: leg residual RMS {rms_before:.4g} {model.unit} with CONFIG's "
                         f"geometry ({rms_before / model.scale:.1%} of its size); check the unit (legs and positions "
                         f"in {model.unit}), the column order and that poses are platform -> base")
    t0 = time.perf_counter()
    result = identify(nominal, fit, groups, scale=model.scale)
    identify_s = time.perf_counter() - t0
    if result.unidentifiable and args.strict:
        texts = "; ".join(d.text for d in result.unidentifiable)
        raise InputError(f"rank-deficient identification (--strict): {len(result.unidentifiable)} parameter "
                         f"direction(s) the data cannot identify (not seen at all, or standard error above "
                         f"{result.se_limit:.3g} {model.unit}): {texts}")
    if not result.converged:
        raise InputError(f"the identification did not converge in {result.iterations} Gauss-Newton iterations")
    values, per_leg = _identified_values(result.geometry, groups)
    header = [f"# Calibrated by glpma-fk calibrate from {Path(args.data).name} ({len(fit_index)} measurements "
              f"fitted, {held} held out): {', '.join(_key(nominal, g) for g in groups)} identified; leg residual RMS "
              f"{rms_before:.4g} -> {_rms(leg_residuals(result.geometry, fit)):.4g} {model.unit}.",
              f"# Everything else as in {config_path.name}, whose comments describe the nominal geometry.", "#"]
    if result.unidentifiable:
        header[-1:-1] = [f"# {len(result.unidentifiable)} parameter direction(s) the data did not identify stay as in "
                         f"{config_path.name} (the command's warnings name them)."]
    if result.gauges:
        header[-1:-1] = [f"# {len(result.gauges)} gauge direction(s) of the leg model (no measurement separates "
                         f"them) stay as in {config_path.name}."]
    if nominal.actuated:
        offsets_comment = [f"# Zero offsets of the actuators ({_offset_unit(nominal, model.unit)}), identified by "
                           f"glpma-fk calibrate: added to", "# every reading before the forward kinematics."]
    else:
        offsets_comment = [f"# Zero offsets of the leg sensors ({model.unit}), identified by glpma-fk calibrate: "
                           f"added to every", "# measured leg length before the forward kinematics."]
    new_text = edit_config(config_path.read_text(), values, header, offsets_comment, per_leg,
                           after="legs" if nominal.actuated else "platform")
    new_doc = check_edit(new_text, values, doc, model.scale, per_leg)
    new_model = model_from_dict(new_doc, str(out))             # NEW.yaml loads as a config (raises otherwise)
    _write(out, new_text)
    t0 = time.perf_counter()
    pose_errors = {"before": holdout_pose_errors(model, hold), "after": holdout_pose_errors(new_model, hold)} \
        if len(hold) else None
    holdout_fk_s = time.perf_counter() - t0
    return _report(args, model, config_path, meas, fit, hold, nominal, result, groups, bag, pose_errors,
                   (identify_s, holdout_fk_s, time.perf_counter() - t_start))


def _key(nominal, group: str) -> str:
    """The YAML key of ``group`` (an actuated family's: a key of each leg, or actuator_offsets)."""
    return FAMILY_KEYS[group] if nominal.actuated else KEYS[group]


def _offset_unit(nominal, unit: str) -> str:
    return "rad" if nominal.kind == REVOLUTE else unit


def _identified_values(geometry, groups) -> tuple:
    """(top-level YAML key -> value, leg key -> one value per leg) of the identified groups."""
    top, per_leg = {}, {}
    for g in groups:
        value = getattr(geometry, FIELD[g])
        if not geometry.actuated or g == "offsets":
            top[_key(geometry, g)] = value
        else:
            per_leg[FAMILY_KEYS[g]] = list(value)
    return top, per_leg


def holdout_pose_errors(model, hold: Measurements) -> dict:
    """The forward kinematics of ``model`` on the held-out leg readings against their measured poses:
    each solve is the compiled local solve (Levenberg-Marquardt, at most :data:`HOLDOUT_FK_MAX_ITER`
    iterations: decided by the work done) from the measured pose, so it finds the assembly mode the
    platform was in.  A solve counts when it converges, or, with redundant legs, ends at a stationary
    point of the leg residuals (the least-squares pose of legs that the geometry and the noise leave
    slightly inconsistent).  Position error: distance between the platform origins (config unit);
    rotation error: angle of ``R_fk R_measured^T`` (degrees)."""
    solver, dim = LocalSolver(model), hold.position.shape[1]
    positions, angles = [], []
    for legs, p, R in zip(hold.legs, hold.position, hold.rotation):
        p3, R3 = np.zeros(3), np.eye(3)
        p3[:dim], R3[:dim, :dim] = p, R
        x0 = model.variables_from_pose(p3, quaternion_from_matrix(R3))
        try:
            legs_in = model.legs_from_sensors(legs)
        except InputError:                  # a reading outside the model's limits: no solve, not counted
            continue
        res = solver.solve(x0, legs_in, max_iter=HOLDOUT_FK_MAX_ITER)
        if res is None or not (res.converged or (model.redundancy > 0 and res.stationarity <= STATIONARY)):
            continue
        positions.append(float(np.linalg.norm(res.position[:dim] - p)))
        cos = (np.trace(matrix_from_quaternion(res.orientation) @ R3.T) - 1.0) / 2.0
        angles.append(math.degrees(math.acos(min(1.0, max(-1.0, cos)))))
    return {"solved": len(positions), "position_rms": _rms(positions), "position_max": max(positions, default=None),
            "rotation_rms_deg": _rms(angles), "rotation_max_deg": max(angles, default=None)}



def _write(path: Path, text_: str) -> None:
    """Write atomically: a file next to ``path``, then renamed over it."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent if str(path.parent) else ".")
        with os.fdopen(fd, "w") as f:
            f.write(text_)
        os.replace(tmp, path)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None


def _finite(v):
    return float(v) if v is not None and math.isfinite(v) else None


def _direction(d) -> dict:
    out = {"legs": list(d.legs), "text": d.text, "se": _finite(d.se), "singular_value": d.singular_value,
           "rank_deficient": d.rank_deficient, "components": d.components}
    if d.gauge:
        out.update(gauge=d.gauge, axis=d.axis)
    return out


def _warning(d, unit: str, se_limit: float) -> str:
    why = ("not seen by the data at all" if d.rank_deficient else
           f"standard error {d.se:.3g} {unit}, above {se_limit:.3g} {unit}")
    return f"left at nominal ({why}): {d.text}"


def _report(args, model, config_path, meas, fit, hold, nominal, result, groups, bag, pose_errors, times) -> dict:
    finite = _finite
    identify_s, holdout_fk_s, total_s = times
    obs = result.observability
    return {
        "config": str(config_path), "data": str(args.data), "out": str(args.out), "kind": model.kind,
        "unit": model.unit, "identify": [_key(nominal, g) for g in groups],
        "offset_unit": _offset_unit(nominal, model.unit),
        "measurements": len(meas), "fitted": len(fit), "held_out": len(hold), "seed": args.seed,
        "rms_before": _rms(leg_residuals(nominal, fit)), "rms_after": _rms(leg_residuals(result.geometry, fit)),
        "holdout_rms_before": _rms(leg_residuals(nominal, hold)) if len(hold) else None,
        "holdout_rms_after": _rms(leg_residuals(result.geometry, hold)) if len(hold) else None,
        "holdout_pose": pose_errors,
        "condition_number": finite(result.condition_number),
        "observability": {"o1": obs.o1, "o3": obs.o3, "condition_number": finite(obs.condition_number),
                          "singular_values": [float(v) for v in obs.singular_values]},
        "parameters": [{"name": p.name, "leg": p.leg, "legs": list(p.legs), "group": _key(nominal, p.group),
                        "axis": p.axis, "nominal": p.nominal, "value": p.value, "se": finite(p.se),
                        "fixed_share": p.fixed_share, "unit": _parameter_unit(p, model.unit)}
                       for p in result.parameters],
        "gauges": [_direction(d) for d in result.gauges],
        "residual_std": [float(s) for s in result.residual_std],
        "unidentifiable": [_direction(d) for d in result.unidentifiable],
        "warnings": [_warning(d, model.unit, result.se_limit) for d in result.unidentifiable],
        "se_limit": result.se_limit,
        "weak": [_direction(d) for d in result.weak],
        "weak_se_threshold": WEAK_SE_SHARE * model.scale,
        "iterations": result.iterations, "identify_s": identify_s, "holdout_fk_s": holdout_fk_s,
        "elapsed_s": total_s,
        "bag": None if bag is None else bag.as_dict()}


def _parameter_unit(p, unit: str) -> str:
    """A parameter's unit: the config unit, "rad" (a revolute actuator's offset) or "1" (a component of a
    rail's unit direction)."""
    return {"length": unit, "angle": "rad", "direction": "1"}[p.quantity]


def text(r: dict) -> str:
    u = r["unit"]
    lines = [f"{PROG}: {r['kind']} ({Path(r['config']).name}, {u}) from {r['data']}: {r['measurements']} measurements, "
             f"{r['fitted']} fitted, {r['held_out']} held out (seed {r['seed']})"]
    if r["bag"]:
        b = r["bag"]
        lines.append(f"  bag: {b['paired']} pairs of {b['legs_messages']} leg readings on {b['legs_topic']} and "
                     f"{b['pose_messages']} poses on {b['pose_topic']}")
    per_leg = sum(1 for p in r["parameters"] if 1 in p["legs"])
    lines += [f"identified {' '.join(r['identify'])}: {per_leg} parameters per leg, {len(r['parameters'])} in all, "
              f"{r['iterations']} Gauss-Newton iterations, {r['identify_s'] * 1e3:.1f} ms",
              f"leg residual RMS ({u}):        before       after",
              f"  fitted measurements  {r['rms_before']:11.5f} {r['rms_after']:11.5f}"]
    if r["held_out"]:
        lines.append(f"  held out             {r['holdout_rms_before']:11.5f} {r['holdout_rms_after']:11.5f}")
        lines += _pose_lines(r["holdout_pose"], u, r["held_out"])
    o = r["observability"]
    lines += [f"observability (singular values per pose): O1 {o['o1']:.4g} (Borm & Menq), O3 {o['o3']:.4g} "
              f"(smallest), condition number {r['condition_number']:.4g}",
              f"parameters ({_units_phrase(r)}): nominal -> identified +- standard error"]
    width = max(len(p["name"]) for p in r["parameters"])
    for p in r["parameters"]:
        note = ""
        if p["fixed_share"] >= 1.0 - NAMED_COMPONENT ** 2:
            note = "  (left at nominal)"
        elif p["fixed_share"] >= NAMED_COMPONENT ** 2:
            note = f"  ({p['fixed_share']:.0%} in directions left at nominal)"
        if p["unit"] == u:
            lines.append(f"  {p['name']:<{width}} {p['nominal']:14.6f} -> {p['value']:14.6f} +- {p['se']:.4f}{note}")
        else:                               # radians, unit-vector components: small numbers, more digits
            lines.append(f"  {p['name']:<{width}} {p['nominal']:14.8f} -> {p['value']:14.8f} +- {p['se']:.2g}{note}")
    if r["weak"]:
        lines.append(f"weakly identified directions (standard error above {r['weak_se_threshold']:.3g} {u}):")
        lines += [f"  +- {d['se']:.3g} {u}: {d['text']}" for d in r["weak"]]
    elif r["unidentifiable"]:
        lines.append(f"no estimated direction has a standard error above {r['weak_se_threshold']:.3g} {u}")
    else:
        lines.append("every parameter direction identified (no standard error above "
                     f"{r['weak_se_threshold']:.3g} {u})")
    if r["gauges"]:
        lines.append("gauge directions (no measurement separates them; kept at nominal):")
        lines += [f"  {phrase}" for phrase in _gauge_phrases(r["gauges"])]
    lines += [f"warning: {w}" for w in r["warnings"]]
    lines.append(f"wrote {r['out']}")
    return "\n".join(lines)


def _units_phrase(r: dict) -> str:
    """The units of the parameter lines: the config unit, and those of the others where there are."""
    other = {p["unit"] for p in r["parameters"]} - {r["unit"]}
    words = {"rad": "offsets in rad", "1": "rail directions as unit vectors"}
    return "; ".join([r["unit"], *(words[o] for o in sorted(other))])


def _gauge_phrases(gauges: list) -> list:
    """The gauge directions in words, one line per kind of gauge with the legs (and coordinates) it has."""
    legs, axes = {}, {}
    for d in gauges:
        legs.setdefault(d["gauge"], []).extend(d["legs"])
        axes.setdefault(d["gauge"], []).append(d["axis"])
    return [gauge_text(name, sorted(set(legs[name])), list(dict.fromkeys(axes[name]))) for name in legs]


def _pose_lines(pose: dict, unit: str, held: int) -> list:
    """The held-out forward kinematics' errors, before and after, as report lines."""
    def cell(side, key, digits):
        v = pose[side][key]
        return f"{'-':>11}" if v is None else f"{v:11.{digits}f}"
    rows = [(f"position error RMS ({unit})", "position_rms", 5), (f"position error max ({unit})", "position_max", 5),
            ("rotation error RMS (deg)", "rotation_rms_deg", 6), ("rotation error max (deg)", "rotation_max_deg", 6)]
    width = max(len(label) for label, _, _ in rows)
    return ([f"held-out forward kinematics, from the measured pose ({pose['before']['solved']} and "
             f"{pose['after']['solved']} of {held} solved):"] +
            [f"  {label:<{width}} {cell('before', key, d)} {cell('after', key, d)}" for label, key, d in rows])
