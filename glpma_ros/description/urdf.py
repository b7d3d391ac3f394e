"""The URDF of a manipulator's loop-cut tree (:class:`~glpma_ros.description.mechanism.Mechanism`):
plain URDF 1.0 (no xacro), metres and radians, valid for urdfdom (``check_urdf``) and
``robot_state_publisher``.

Geometry without meshes: a disc for the base and one for the platform (through their joints),
a sphere at every joint, a tube from each base joint and a rod to each platform joint (the
prismatic actuator's two parts, so that a leg visibly gets longer); for an actuated family
(Delta, 6-RUS, 3-RRR) a bar for each crank (origin to tip) and each rod (its whole length).  With ``meshes`` (a folder)
a link whose mesh file is there shows the mesh instead: ``<link>.stl`` (or ``.dae``, ``.obj``),
the link named without the prefix (``base_link.stl``, ``platform_link.dae``, ``leg3_rod.stl``),
and for the legs also ``leg_<part>.<ext>`` shared by every leg (``leg_cylinder.stl``,
``leg_rod.stl``); a mesh is in metres in its link's frame.  No ROS import here.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .mechanism import FIXED, Mechanism

#: mesh file extensions looked for, in this order
MESH_EXTENSIONS = (".stl", ".dae", ".obj")
#: sizes of the simple geometry, as shares of the manipulator's size (its ``scale``): joint spheres'
#: radius, tube and rod radii, the discs' thickness
JOINT_RADIUS = 0.03
TUBE_RADIUS = 0.02
ROD_RADIUS = 0.012
DISC_THICKNESS = 0.02
#: the tube and the rod are each this share of a typical leg length (the config's example legs,
#: else its size) long: the leg looks whole up to 2 x this share of that length
LEG_PART_SHARE = 0.6
#: a URDF revolute or prismatic joint needs an effort and a velocity limit; the config says
#: nothing of the dynamics, so these are placeholders (N or N m, m/s or rad/s) that no ROS tool
#: used here reads (robot_state_publisher ignores them; give your own to a planner)
EFFORT_LIMIT = 1000.0
VELOCITY_LIMIT = 10.0
#: colours (r, g, b, a), those of the node's ~/markers
COLOURS = {"base": (0.55, 0.55, 0.6, 1.0), "tube": (0.1, 0.35, 1.0, 1.0), "rod": (0.8, 0.8, 0.82, 1.0),
           "joint": (0.2, 0.2, 0.2, 1.0), "platform": (0.95, 0.65, 0.1, 1.0)}


def _num(v: float) -> str:
    """A number as URDF text: the shortest repr that reads back as the same double (no rounding of
    the geometry: the joints' states reproduce the pose to round-off)."""
    v = float(v)
    return "0" if v == 0.0 else repr(v)


def _vec(values) -> str:
    return " ".join(_num(v) for v in values)


class UrdfWriter:
    """Writes :class:`Mechanism` ``mech`` as URDF text (:meth:`text`)."""

    def __init__(self, mech: Mechanism, robot_name: str = "glpma_manipulator", meshes: str | Path | None = None):
        self.mech = mech
        self.robot_name = robot_name
        self.meshes = None if meshes is None else Path(meshes).expanduser().resolve()
        s = mech.scale_m
        self.joint_r, self.tube_r, self.rod_r, self.disc = (JOINT_RADIUS * s, TUBE_RADIUS * s, ROD_RADIUS * s,
                                                            DISC_THICKNESS * s)
        example = getattr(mech.model, "example_leg_lengths", None)
        typical = float(np.median(example)) * mech.metres if example is not None else s
        self.part_length = LEG_PART_SHARE * typical
        self.meshes_used: list = []

    # -- helpers ----------------------------------------------------------------------------
    def _mesh(self, link: str):
        """The mesh file for ``link`` (prefix-free name) in the meshes folder, or None."""
        if self.meshes is None:
            return None
        names = [link]
        if link.startswith("leg"):
            names.append("leg_" + link.split("_", 1)[1])
        for name in names:
            for ext in MESH_EXTENSIONS:
                path = self.meshes / f"{name}{ext}"
                if path.is_file():
                    return path
        return None

    @staticmethod
    def _origin(parent, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> None:
        ET.SubElement(parent, "origin", xyz=_vec(xyz), rpy=_vec(rpy))

    def _visual(self, link_el, geometry: str, attrs: dict, material: str, xyz=(0.0, 0.0, 0.0),
                rpy=(0.0, 0.0, 0.0)) -> None:
        visual = ET.SubElement(link_el, "visual")
        self._origin(visual, xyz, rpy)
        geom = ET.SubElement(visual, "geometry")
        ET.SubElement(geom, geometry, {k: _num(v) if not isinstance(v, str) else v for k, v in attrs.items()})
        ET.SubElement(visual, "material", name=material)

    def _disc(self, link_el, points: np.ndarray, material: str, below: bool) -> None:
        """A disc through ``points`` (the joints, in the link's frame): centred on their centroid,
        its radius reaching the farthest, half its thickness under them (base) or over them
        (platform).  Planar points lie in z = 0, hexapod points on a plane of constant z (the
        shipped configs) or near one; the disc is horizontal in the link's frame."""
        centre = points.mean(axis=0)
        radius = float(np.max(np.linalg.norm(points[:, :2] - centre[:2], axis=1))) + self.joint_r
        offset = -0.5 * self.disc if below else 0.5 * self.disc
        self._visual(link_el, "cylinder", {"radius": radius, "length": self.disc}, material,
                     (centre[0], centre[1], centre[2] + offset))

    def _sphere(self, link_el, centre=(0.0, 0.0, 0.0)) -> None:
        self._visual(link_el, "sphere", {"radius": self.joint_r}, self.mech.name("glpma_joint"), centre)

    def _link(self, robot, name: str, role: str) -> None:
        """A link with its geometry: ``role`` says which (base, platform, u_cross, cylinder, rod, s_cross, end)."""
        m = self.mech
        el = ET.SubElement(robot, "link", name=name)
        mesh = self._mesh(name[len(m.prefix):])
        if mesh is not None:
            self.meshes_used.append(mesh)
            visual = ET.SubElement(el, "visual")
            self._origin(visual)
            ET.SubElement(ET.SubElement(visual, "geometry"), "mesh", filename=mesh.as_uri())
            return
        axis_x = m.planar          # the planar legs move along x, the hexapod's along z
        along = (0.0, 0.5 * math.pi, 0.0) if axis_x else (0.0, 0.0, 0.0)

        def on_axis(t):
            return (t, 0.0, 0.0) if axis_x else (0.0, 0.0, t)
        if m.actuated and role in ("crank", "rod"):
            self._bar(el, name, role)
        elif role == "carriage":
            self._sphere(el)
        elif role == "base":
            self._disc(el, m.base_m, m.name("glpma_base"), below=True)
            for a in m.base_m:
                self._sphere(el, a)
        elif role == "platform":
            self._disc(el, m.platform_m, m.name("glpma_platform"), below=False)
        elif role == "cylinder":
            self._visual(el, "cylinder", {"radius": self.tube_r, "length": self.part_length}, m.name("glpma_tube"),
                         on_axis(0.5 * self.part_length), along)
        elif role == "rod":
            self._visual(el, "cylinder", {"radius": self.rod_r, "length": self.part_length}, m.name("glpma_rod"),
                         on_axis(-0.5 * self.part_length), along)
        elif role == "end":
            self._sphere(el)

    def _bar(self, link_el, name: str, role: str) -> None:
        """An actuated leg's crank (from the link's origin to the crank tip) or rod (from the link's origin
        along its +z axis, planar +x, the rod's length) as a cylinder."""
        m = self.mech
        leg = next(j.leg for j in m.joints if j.child == name)
        if role == "crank":
            tip = m.crank_m[leg]
        else:
            length = float(m.rods_m[leg])
            tip = np.array([length, 0.0, 0.0]) if m.planar else np.array([0.0, 0.0, length])
        length = float(np.linalg.norm(tip))
        pitch = math.atan2(math.hypot(tip[0], tip[1]), tip[2])       # the cylinder's z axis turned onto tip:
        yaw = math.atan2(tip[1], tip[0])                              # Rz(yaw) Ry(pitch) e_z = tip / |tip|
        radius, material = (self.tube_r, "glpma_tube") if role == "crank" else (self.rod_r, "glpma_rod")
        self._visual(link_el, "cylinder", {"radius": radius, "length": length}, m.name(material), 0.5 * tip,
                     (0.0, pitch, yaw))

    def _joint(self, robot, j) -> None:
        el = ET.SubElement(robot, "joint", name=j.name, type=j.type)
        self._origin(el, j.origin)
        ET.SubElement(el, "parent", link=j.parent)
        ET.SubElement(el, "child", link=j.child)
        if j.type == FIXED:
            return
        ET.SubElement(el, "axis", xyz=_vec(j.axis))
        lo, hi = j.limits
        ET.SubElement(el, "limit", lower=_num(lo), upper=_num(hi), effort=_num(EFFORT_LIMIT),
                      velocity=_num(VELOCITY_LIMIT))

    # -- the document -----------------------------------------------------------------------
    def element(self) -> ET.Element:
        m = self.mech
        robot = ET.Element("robot", name=self.robot_name)
        for key, rgba in COLOURS.items():
            ET.SubElement(ET.SubElement(robot, "material", name=m.name(f"glpma_{key}")), "color", rgba=_vec(rgba))
        self._link(robot, m.base_link, "base")
        for j in m.joints:
            role = "platform" if j.child == m.platform_link else j.child[len(m.leg_link(j.leg, "")):]
            if role.startswith("s_cross") or role == "u_cross":
                role = "cross"
            self._link(robot, j.child, role)
            self._joint(robot, j)
        return robot

    def text(self, source: str = "") -> str:
        robot = self.element()
        ET.indent(robot)
        m = self.mech
        note = (f" Generated by glpma-fk urdf{' from ' + source if source else ''}: the loop-cut tree of a "
                f"{m.model.kind} with {m.n_legs} legs (metres, radians). Each leg is a chain "
                f"from {m.base_link} to {m.name('leg<i>_end')} at its platform joint; "
                f"{m.platform_link} hangs from {m.leg_link(0, 'end')} by the fixed joint "
                f"{m.name('platform_mount')}. Feed it every joint's state (the glpma_fk node's "
                f"~/mechanism_joint_states) and every leg ends at its platform joint. ")
        body = ET.tostring(robot, encoding="unicode")
        return f'<?xml version="1.0"?>\n<!--{note}-->\n{body}\n'


def urdf_text(model, robot_name: str = "glpma_manipulator", prefix: str = "", meshes=None, source: str = "",
              passive_limits=None) -> str:
    """The URDF of ``model`` (a loaded config) as text; see :class:`UrdfWriter`."""
    mech = Mechanism(model, prefix=prefix, passive_limits=passive_limits)
    return UrdfWriter(mech, robot_name, meshes).text(source)
