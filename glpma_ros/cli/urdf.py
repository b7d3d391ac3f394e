"""``glpma-fk urdf``: the manipulator's URDF (the loop-cut tree of its legs' joints) for robot_state_publisher."""
from __future__ import annotations

import sys
from pathlib import Path

from ..config import load_manipulator, resolve_config
from ..description.urdf import urdf_text
from ..errors import GlpmaError
from ..node.params import URDF_PREFIX
from .api import OneLineParser, command_main, manipulator_parser

#: the command's --help text
DESCRIPTION = ("Write the URDF of the manipulator of CONFIG (plain URDF, no xacro; metres, radians): "
               "base_link, each leg a chain of its joints as built (hexapod: universal joint legI_u1, legI_u2, "
               "prismatic legI_actuator, spherical joint legI_s1, legI_s2, legI_s3; 3-RPR: legI_base, "
               "legI_actuator, legI_platform) ending at its platform joint (link legI_end), platform_link fixed "
               "to leg1_end (the loop cut). The glpma_fk node publishes every joint's state on "
               "~/mechanism_joint_states (publish_joint_states:=true). Joint naming: doc/interface.md, "
               "\"The URDF\".")


def build_parser() -> OneLineParser:
    q = manipulator_parser("glpma-fk urdf", DESCRIPTION)
    q.add_argument("--out", default=None, metavar="FILE", help="write the URDF here (default: stdout)")
    q.add_argument("--prefix", default="", metavar="NAME_",
                   help="put before every link, joint and material name (e.g. left_), for two robots in one tree")
    q.add_argument("--meshes", default=None, metavar="DIR",
                   help="a folder of meshes (metres, in their link's frame): a link named LINK (without the prefix) "
                        "shows DIR/LINK.stl (or .dae, .obj) where it exists, a leg's link also DIR/leg_PART.stl "
                        "(e.g. leg_cylinder.stl, leg_rod.stl for every leg); the other links keep the simple geometry")
    q.add_argument("--name", default=None, help="the robot's name (default: the config's file name)")
    return q


@command_main
def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if not URDF_PREFIX.fullmatch(args.prefix):
        raise GlpmaError(f"--prefix {args.prefix!r}: use letters, digits, '_' and '/' only")
    if args.meshes is not None and not Path(args.meshes).expanduser().is_dir():
        raise GlpmaError(f"--meshes {args.meshes}: not a folder")
    path = resolve_config(args.config)
    model = load_manipulator(path)
    text = urdf_text(model, robot_name=args.name or Path(str(path)).stem, prefix=args.prefix, meshes=args.meshes,
                     source=Path(str(path)).name, passive_limits=getattr(model, "passive_limits", None))
    if args.out is None:
        sys.stdout.write(text)
        return 0
    out = Path(args.out)
    if out.resolve() == Path(str(path)).resolve():
        raise GlpmaError(f"--out {args.out} is the config itself; an input file is never overwritten")
    try:
        out.write_text(text)
    except OSError as exc:
        raise GlpmaError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(f"wrote {out} ({model.n_legs} legs)", file=sys.stderr)
    return 0
