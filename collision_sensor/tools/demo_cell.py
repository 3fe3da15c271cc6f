"""Generate the bundled demo cell: the paper's application with our own models.

Benchetrit, Lenz and Shoham (1998) demonstrate the sensor on a 6-DOF articulated robot (more than
2000 triangles) working at a washing machine (more than 3000 triangles), and show a SCARA whose
links are split into sub-groups (their Fig. 1). This module builds all three from trimesh
primitives, without booleans, and writes them with the robot descriptions, the scene and the
bundled joint sequences::

    python -m collision_sensor.tools.demo_cell [--output-dir DIR]

rewrites, under DIR (default: this source tree),

- ``meshes/demo_cell/*.stl``: binary STL, every mesh watertight with consistent winding;
- ``config/demo_arm.urdf``, ``config/demo_arm.srdf``: the arm (``package://collision_sensor``
  mesh URIs) and its never-colliding adjacent pairs;
- ``config/scara.urdf``: the SCARA, each link split into several ``<collision>`` elements;
- ``config/demo_scene.yaml``: washer cabinet, drum, open door, floor;
- ``config/sequences/*.csv`` and the bag ``config/sequences/paper_experiment/``;
- the bag ``config/sequences/moving_part/``: the dynamic scene (:func:`moving_part`), joint
  states and the node's ``scene`` arrays.

The output is deterministic: the same bytes on every run (vertices are rounded to 1 um before
the float32 STL encoding; CSV values to 1e-6).

Frames: the arm's base frame is the world frame, z up, the floor top at z = -0.002 m. The washer
stands in front of the arm: its frame (all ``washer_*`` objects share it) has the origin at the
bottom centre of the cabinet's front face, x pointing into the machine, and sits at
``WASHER_XYZ`` in the world. The porthole is centred at height ``HOLE_Z``.
"""
import argparse
import math
import os
import shutil
import struct
import sys
from typing import Dict, Optional

import numpy as np
import trimesh

from collision_sensor.model.sequences import JointSequence, write_sequence
from collision_sensor.model.share import SOURCE_ROOT

PACKAGE = 'collision_sensor'
MESH_SUBDIR = 'demo_cell'

# --- the arm's kinematics (m, rad); link frames sit on the joint axes --------------------------
ARM_JOINTS = (
    # name, parent, child, origin xyz in parent, axis, (lower, upper)
    ('shoulder_pan', 'base_link', 'shoulder_link', (0.0, 0.0, 0.19), (0, 0, 1), (-2.9, 2.9)),
    ('shoulder_lift', 'shoulder_link', 'upper_arm_link', (0.0, 0.0, 0.26), (0, 1, 0),
     (-2.0, 2.0)),
    ('elbow', 'upper_arm_link', 'forearm_link', (0.0, 0.0, 0.45), (0, 1, 0), (-2.5, 2.5)),
    ('wrist_roll', 'forearm_link', 'wrist_roll_link', (0.32, 0.0, 0.0), (1, 0, 0), (-3.0, 3.0)),
    ('wrist_pitch', 'wrist_roll_link', 'wrist_pitch_link', (0.10, 0.0, 0.0), (0, 1, 0),
     (-2.1, 2.1)),
    ('tool_roll', 'wrist_pitch_link', 'tool_link', (0.08, 0.0, 0.0), (1, 0, 0), (-3.1, 3.1)),
)
ARM_LINKS = ('base_link', 'shoulder_link', 'upper_arm_link', 'forearm_link', 'wrist_roll_link',
             'wrist_pitch_link', 'tool_link')
ARM_JOINT_NAMES = tuple(joint[0] for joint in ARM_JOINTS)

# --- the washer (washer frame, m) -------------------------------------------------------------
WASHER_XYZ = (0.75, 0.0, 0.0)
CABINET_DEPTH, CABINET_WIDTH, CABINET_HEIGHT = 0.60, 0.60, 0.85
WALL = 0.02
PANEL_GAP = 0.0005      # between cabinet panels, so that no two closed panels share a vertex
HOLE_Z, HOLE_RADIUS = 0.50, 0.17
DRUM_FRONT, DRUM_DEPTH = 0.04, 0.50
DRUM_INNER, DRUM_OUTER = 0.24, 0.26
DOOR_OPEN = math.radians(100.0)  # swung about the hinge, towards the arm
FLOOR_SIZE = (2.0, 2.0, 0.02)
FLOOR_XYZ = (0.4, 0.0, -0.012)

VERTEX_DECIMALS = 6
SEQUENCE_DECIMALS = 6
SEQUENCE_RATE = 50.0    # Hz of the designed paths


# === shapes ====================================================================================
# Every helper returns one closed, outward-wound trimesh; a part made of several helpers is a
# mesh with several closed components (watertight: every edge has exactly two faces).

def _frame(z_axis, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Return T (4, 4) taking a shape built along +z to one along ``z_axis`` at ``origin``."""
    z = np.asarray(z_axis, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = origin
    return T


def _capsule(p0, p1, radius, sections=24) -> trimesh.Trimesh:
    """Capsule with the axis from ``p0`` to ``p1`` (the centres of its end spheres)."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    mesh = trimesh.creation.capsule(height=float(np.linalg.norm(p1 - p0)), radius=radius,
                                    count=[sections, sections // 2])
    mesh.apply_transform(_frame(p1 - p0, (p0 + p1) / 2.0))
    return mesh


def _rounded_cylinder(radius, length, fillet, axis=(0, 0, 1), centre=(0, 0, 0),
                      sections=32, fillet_steps=4) -> trimesh.Trimesh:
    """Cylinder with rounded rims, revolved from its profile; centred, along ``axis``."""
    half = length / 2.0
    profile = [(0.0, -half)]
    for z_sign in (-1.0, 1.0):
        # quarter arcs at the bottom rim then the top rim, walking up the outside
        start = -math.pi / 2.0 if z_sign < 0 else 0.0
        for step in range(fillet_steps + 1):
            angle = start + (math.pi / 2.0) * step / fillet_steps
            profile.append((radius - fillet + fillet * math.cos(angle),
                            z_sign * (half - fillet) + fillet * math.sin(angle)))
    profile.append((0.0, half))
    mesh = trimesh.creation.revolve(np.array(profile), sections=sections)
    mesh.apply_transform(_frame(axis, centre))
    return mesh


def _torus(major, minor, axis=(0, 0, 1), centre=(0, 0, 0), sections=(32, 12)):
    """Torus around ``axis``; tube radius ``minor``."""
    return trimesh.creation.torus(major, minor, major_sections=sections[0],
                                  minor_sections=sections[1], transform=_frame(axis, centre))


def _rounded_box(half_extents, radius, centre=(0, 0, 0), segments=16, rings=8):
    """Box with rounded edges and corners: a sphere of ``radius`` swept over a box.

    Built from a UV sphere whose vertex rows and columns avoid the coordinate planes, split at
    those planes and pushed out by ``half_extents`` (the Minkowski sum of box and sphere); the
    poles land in the middle of the top and bottom faces.
    :param half_extents: (3,) half sizes of the inner box; the outer size adds ``radius``.
    """
    assert segments % 4 == 0 and rings % 2 == 0
    phis = (np.arange(segments) + 0.5) * 2.0 * math.pi / segments
    thetas = (np.arange(rings) + 0.5) * math.pi / rings
    ring_points = np.array([[math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]
                            for t in thetas for p in phis])
    directions = np.vstack([[0.0, 0.0, 1.0], ring_points, [0.0, 0.0, -1.0]])
    faces = []
    bottom = len(directions) - 1

    def ring(r, s):
        return 1 + r * segments + s % segments
    for s in range(segments):
        faces.append((0, ring(0, s), ring(0, s + 1)))
        faces.append((bottom, ring(rings - 1, s + 1), ring(rings - 1, s)))
        for r in range(rings - 1):
            faces.append((ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)))
            faces.append((ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)))
    vertices = radius * directions + np.sign(directions) * np.asarray(half_extents) \
        + np.asarray(centre)
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def _box(lower, upper) -> trimesh.Trimesh:
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    return trimesh.creation.box(extents=upper - lower,
                                transform=trimesh.transformations.translation_matrix(
                                    (lower + upper) / 2.0))


def _extrude_yz(points, triangles, thickness) -> trimesh.Trimesh:
    """Extrude a triangulated (y, z) region along x over [0, thickness].

    :param points: (n, 2) float (y, z) vertices.
    :param triangles: (m, 3) int, counter-clockwise in the (y, z) plane.
    """
    points = np.asarray(points, dtype=float)
    n = len(points)
    back = np.column_stack([np.full(n, thickness), points])
    front = np.column_stack([np.zeros(n), points])
    triangles = np.asarray(triangles)
    faces = [triangles, triangles[:, [0, 2, 1]] + n]   # back looks +x, front looks -x
    directed = {}
    for a, b, c in triangles:
        for edge in ((a, b), (b, c), (c, a)):
            directed[edge] = directed.get(edge, 0) + 1
    sides = []
    for (a, b) in sorted(directed):
        if (b, a) not in directed:  # boundary edge: close it with a side quad
            sides.append((b, a, a + n))
            sides.append((b, a + n, b + n))
    faces.append(np.array(sides))
    return trimesh.Trimesh(np.vstack([back, front]), np.vstack(faces), process=False)


def _plate_with_hole(y_range, z_range, thickness, hole_centre, hole_radius, sections=72):
    """Plate spanning ``y_range`` x ``z_range`` over x in [0, thickness], a round hole in it.

    The region between the hole and the rectangle is triangulated as a strip: hole vertex i
    and the rectangle point hit by the ray from the hole centre at the same angle, with the
    rectangle's corners inserted where the rays pass them.
    """
    (y0, y1), (z0, z1) = y_range, z_range
    centre = np.asarray(hole_centre, dtype=float)
    angles = 2.0 * math.pi * (np.arange(sections) + 0.5) / sections
    circle = centre + hole_radius * np.column_stack([np.cos(angles), np.sin(angles)])

    def ray_to_rectangle(angle):
        direction = np.array([math.cos(angle), math.sin(angle)])
        distances = []
        for axis, (low, high) in enumerate(((y0, y1), (z0, z1))):
            if abs(direction[axis]) > 1e-12:
                bound = high if direction[axis] > 0 else low
                distances.append((bound - centre[axis]) / direction[axis])
        return centre + min(distances) * direction

    corners = [(y1, z1), (y0, z1), (y0, z0), (y1, z0)]
    corner_angles = [math.atan2(z - centre[1], y - centre[0]) % (2.0 * math.pi)
                     for y, z in corners]
    points = [tuple(p) for p in circle]
    outer_index = []
    triangles = []
    for i, angle in enumerate(angles):
        points.append(tuple(ray_to_rectangle(angle)))
        outer_index.append(len(points) - 1)
    for i in range(sections):
        j = (i + 1) % sections
        upper = angles[j] if j else angles[j] + 2.0 * math.pi
        chain = [outer_index[i]]
        for corner, corner_angle in sorted(zip(corners, corner_angles), key=lambda c: c[1]):
            if corner_angle < angles[0]:
                corner_angle += 2.0 * math.pi
            if angles[i] < corner_angle < upper:
                points.append(corner)
                chain.append(len(points) - 1)
        chain.append(outer_index[j])
        for a, b in zip(chain[:-1], chain[1:]):
            triangles.append((i, a, b))
        triangles.append((i, outer_index[j], j))
    return _extrude_yz(points, triangles, thickness)


def _merge(*parts) -> trimesh.Trimesh:
    return trimesh.util.concatenate(list(parts))


# === the 6-DOF arm =============================================================================

def arm_link_meshes() -> Dict[str, trimesh.Trimesh]:
    """Return the arm's link meshes, each in its link frame (see ``ARM_JOINTS``)."""
    return {
        # pedestal on the floor, a flange ring on top; the shoulder frame is at z = 0.19
        'base_link': _merge(
            _rounded_cylinder(0.14, 0.18, 0.025, centre=(0, 0, 0.09), sections=48),
            _torus(0.115, 0.012, centre=(0, 0, 0.18), sections=(48, 10))),
        # turret and the shoulder hub across y; the shoulder axis is at z = 0.26
        'shoulder_link': _merge(
            _rounded_cylinder(0.11, 0.17, 0.02, centre=(0, 0, 0.09), sections=40),
            _rounded_cylinder(0.085, 0.24, 0.02, axis=(0, 1, 0), centre=(0, 0, 0.26),
                              sections=40)),
        # the upper arm along z to the elbow at z = 0.45, with the elbow hub across y
        'upper_arm_link': _merge(
            _capsule((0, 0, 0.0), (0, 0, 0.45), 0.06, sections=28),
            _rounded_cylinder(0.065, 0.17, 0.015, axis=(0, 1, 0), centre=(0, 0, 0.45),
                              sections=36)),
        # the forearm along x to the wrist at x = 0.32, a collar ring before the wrist
        'forearm_link': _merge(
            _capsule((0.0, 0, 0), (0.29, 0, 0), 0.045, sections=24),
            _torus(0.045, 0.012, axis=(1, 0, 0), centre=(0.26, 0, 0), sections=(32, 10))),
        # wrist housing up to the pitch axis at x = 0.10
        'wrist_roll_link': _rounded_box((0.025, 0.022, 0.022), 0.018, centre=(0.05, 0, 0)),
        # pitch hub across y and a short neck to the flange at x = 0.08
        'wrist_pitch_link': _merge(
            _rounded_cylinder(0.04, 0.09, 0.012, axis=(0, 1, 0), sections=32),
            _capsule((0.0, 0, 0), (0.055, 0, 0), 0.032, sections=20)),
        # flange disc, gripper body and two fingers; the finger tips reach x = 0.152
        'tool_link': _merge(
            _rounded_cylinder(0.045, 0.02, 0.006, axis=(1, 0, 0), centre=(0.01, 0, 0),
                              sections=32),
            _rounded_box((0.018, 0.03, 0.012), 0.012, centre=(0.05, 0, 0)),
            _capsule((0.08, 0.025, 0), (0.14, 0.025, 0), 0.012, sections=16),
            _capsule((0.08, -0.025, 0), (0.14, -0.025, 0), 0.012, sections=16)),
    }


# === the washer ================================================================================

def washer_meshes() -> Dict[str, trimesh.Trimesh]:
    """Return the washer's parts in the washer frame (see the module docstring)."""
    d, w, h, t, g = CABINET_DEPTH, CABINET_WIDTH / 2.0, CABINET_HEIGHT, WALL, PANEL_GAP
    # The shell: a front panel with the porthole, back, sides, top and bottom, and a control
    # panel; a box around the whole is a poor answer for anything reaching into it.
    cabinet = _merge(
        _plate_with_hole((-w, w), (0.0, h), t, (0.0, HOLE_Z), HOLE_RADIUS, sections=96),
        _box((d - t, -w, 0.0), (d, w, h)),
        _box((t + g, -w, 0.0), (d - t - g, -w + t, h)),
        _box((t + g, w - t, 0.0), (d - t - g, w, h)),
        _box((t + g, -w + t + g, h - t), (d - t - g, w - t - g, h)),
        _box((t + g, -w + t + g, 0.0), (d - t - g, w - t - g, t)),
        _rounded_box((0.03, w - 0.03, 0.02), 0.015, centre=(0.07, 0.0, h + 0.035), segments=24),
    )
    # The drum: a thick-walled cup open towards the door, revolved from its profile (r, z)
    # with z along the drum axis from the closed bottom (z = 0) to the rim (z = DRUM_DEPTH);
    # three lifter ribs on the inside wall.
    steps = 6
    profile = [(0.0, 0.0)]
    for k in range(steps + 1):      # rounded outer bottom edge
        a = -math.pi / 2.0 + (math.pi / 2.0) * k / steps
        profile.append((DRUM_OUTER - 0.03 + 0.03 * math.cos(a), 0.03 + 0.03 * math.sin(a)))
    rim = (DRUM_OUTER - DRUM_INNER) / 2.0
    for k in range(steps + 1):      # rounded rim
        a = (math.pi) * k / steps
        profile.append((DRUM_INNER + rim + rim * math.cos(a),
                        DRUM_DEPTH - rim + rim * math.sin(a)))
    profile += [(DRUM_INNER, 0.03 + t), (DRUM_INNER - 0.02, t), (0.0, t), (0.0, 0.0)]
    drum = trimesh.creation.revolve(np.array(profile), sections=72)
    # the cup opens along +z; turn it to open along -x, rim at x = DRUM_FRONT
    T_washer_drum = _frame((-1.0, 0.0, 0.0), (DRUM_FRONT + DRUM_DEPTH, 0.0, HOLE_Z))
    drum.apply_transform(T_washer_drum)
    ribs = []
    for angle in (math.pi / 2.0, math.pi * 7.0 / 6.0, math.pi * 11.0 / 6.0):
        offset = np.array([0.0, math.cos(angle), math.sin(angle)]) * (DRUM_INNER - 0.005)
        centre = np.array([0.0, 0.0, HOLE_Z]) + offset
        ribs.append(_capsule(centre + (DRUM_FRONT + 0.10, 0, 0),
                             centre + (DRUM_FRONT + DRUM_DEPTH - 0.06, 0, 0), 0.02,
                             sections=16))
    drum = _merge(drum, *ribs)
    # The door, built closed (ring and glass bowl on the porthole, hinge on the -y side), then
    # swung open about the vertical hinge axis towards the arm.
    ring_x = -0.04
    hinge = np.array([ring_x, -0.27, HOLE_Z])
    bowl_profile = [(0.0, -0.01), (0.17, -0.01), (0.19, 0.0), (0.19, 0.012), (0.15, 0.05),
                    (0.0, 0.06), (0.0, 0.04), (0.13, 0.035), (0.165, 0.01), (0.0, 0.01)]
    bowl = trimesh.creation.revolve(np.array(bowl_profile), sections=48)
    bowl.apply_transform(_frame((1.0, 0.0, 0.0), (ring_x, 0.0, HOLE_Z)))
    door = _merge(
        _torus(0.205, 0.035, axis=(1, 0, 0), centre=(ring_x, 0.0, HOLE_Z), sections=(48, 12)),
        bowl,
        _capsule(hinge + (0, 0, -0.09), hinge + (0, 0, 0.09), 0.016, sections=16),
        _capsule(hinge + (0, 0.012, 0.05), (ring_x, -0.22, HOLE_Z + 0.05), 0.012, sections=12),
        _capsule(hinge + (0, 0.012, -0.05), (ring_x, -0.22, HOLE_Z - 0.05), 0.012, sections=12),
    )
    T_open = trimesh.transformations.rotation_matrix(DOOR_OPEN, (0, 0, 1), hinge)
    door.apply_transform(T_open)
    return {'washer_cabinet': cabinet, 'washer_drum': drum, 'washer_door': door}


# === the SCARA (paper Fig. 1: links split into sub-groups) =====================================

# link -> [(element, mesh, origin xyz, origin rpy)]; each element is meshed in its own frame
def scara_elements():
    """Return ``{link: [(element name, mesh, xyz, rpy), ...]}`` for the SCARA."""
    along_x = (0.0, math.pi / 2.0, 0.0)
    return {
        'scara_base': [
            ('foot', _rounded_cylinder(0.16, 0.03, 0.008, sections=40), (0, 0, 0.015),
             (0, 0, 0)),
            ('column', _rounded_cylinder(0.08, 0.36, 0.015, sections=32), (0, 0, 0.21),
             (0, 0, 0)),
            ('cable_box', _rounded_box((0.03, 0.04, 0.08), 0.012), (-0.12, 0, 0.15),
             (0, 0, 0)),
        ],
        'scara_arm1': [
            ('hub', _rounded_cylinder(0.09, 0.07, 0.012, sections=32), (0, 0, 0.035),
             (0, 0, 0)),
            ('beam', _capsule((0, 0, -0.15), (0, 0, 0.15), 0.05), (0.175, 0, 0.035), along_x),
            ('elbow', _rounded_cylinder(0.075, 0.07, 0.012, sections=32), (0.35, 0, 0.035),
             (0, 0, 0)),
        ],
        'scara_arm2': [
            ('hub', _rounded_cylinder(0.07, 0.06, 0.012, sections=32), (0, 0, 0.03),
             (0, 0, 0)),
            ('beam', _capsule((0, 0, -0.12), (0, 0, 0.12), 0.045), (0.15, 0, 0.03), along_x),
            ('motor', _rounded_cylinder(0.06, 0.16, 0.015, sections=32), (0.30, 0, 0.10),
             (0, 0, 0)),
        ],
        'scara_quill': [
            ('shaft', _capsule((0, 0, -0.16), (0, 0, 0.16), 0.016, sections=16), (0, 0, 0.0),
             (0, 0, 0)),
            ('stop', _torus(0.03, 0.01, sections=(24, 8)), (0, 0, 0.12), (0, 0, 0)),
        ],
        'scara_tool': [
            ('flange', _rounded_cylinder(0.035, 0.02, 0.005, sections=24), (0, 0, -0.01),
             (0, 0, 0)),
            ('finger_left', _capsule((0, 0, -0.03), (0, 0, 0.03), 0.01, sections=12),
             (0, 0.018, -0.06), (0, 0, 0)),
            ('finger_right', _capsule((0, 0, -0.03), (0, 0, 0.03), 0.01, sections=12),
             (0, -0.018, -0.06), (0, 0, 0)),
        ],
    }


SCARA_JOINTS = (
    # name, type, parent, child, xyz, axis, (lower, upper)
    ('scara_j1', 'revolute', 'scara_base', 'scara_arm1', (0, 0, 0.40), (0, 0, 1), (-2.5, 2.5)),
    ('scara_j2', 'revolute', 'scara_arm1', 'scara_arm2', (0.35, 0, 0.075), (0, 0, 1),
     (-2.6, 2.6)),
    ('scara_j3', 'prismatic', 'scara_arm2', 'scara_quill', (0.30, 0, -0.02), (0, 0, -1),
     (0.0, 0.15)),
    ('scara_j4', 'revolute', 'scara_quill', 'scara_tool', (0, 0, -0.16), (0, 0, 1),
     (-3.1, 3.1)),
)


# === files =====================================================================================

def _fmt(values) -> str:
    return ' '.join(repr(float(v) + 0.0) for v in values)


def _mesh_uri(name: str) -> str:
    return f'package://{PACKAGE}/meshes/{MESH_SUBDIR}/{name}.stl'


def arm_urdf() -> str:
    """Return the arm's URDF text."""
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by "python -m collision_sensor.tools.demo_cell"; edit that, not this. -->',
             '<!-- 6-DOF arm of the bundled demo cell (the paper\'s application). -->',
             '<robot name="demo_arm">']
    for link in ARM_LINKS:
        geometry = f'<geometry><mesh filename="{_mesh_uri("arm_" + link)}"/></geometry>'
        lines += [f'  <link name="{link}">',
                  f'    <visual>{geometry}</visual>',
                  f'    <collision>{geometry}</collision>',
                  '  </link>']
    for name, parent, child, xyz, axis, (lower, upper) in ARM_JOINTS:
        lines += [f'  <joint name="{name}" type="revolute">',
                  f'    <parent link="{parent}"/>',
                  f'    <child link="{child}"/>',
                  f'    <origin xyz="{_fmt(xyz)}" rpy="0.0 0.0 0.0"/>',
                  f'    <axis xyz="{_fmt(axis)}"/>',
                  f'    <limit lower="{lower!r}" upper="{upper!r}" effort="100.0" '
                  'velocity="2.0"/>',
                  '  </joint>']
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def arm_srdf() -> str:
    """Return the arm's SRDF: adjacent links, which touch at their joints by design."""
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by "python -m collision_sensor.tools.demo_cell"; edit that, not this. -->',
             '<robot name="demo_arm">']
    for _, parent, child, _, _, _ in ARM_JOINTS:
        lines.append(f'  <disable_collisions link1="{parent}" link2="{child}" '
                     'reason="Adjacent"/>')
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def scara_urdf() -> str:
    """Return the SCARA's URDF text: several ``<collision>`` elements per link."""
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by "python -m collision_sensor.tools.demo_cell"; edit that, not this. -->',
             '<!-- SCARA of the paper\'s Fig. 1: each link split into sub-groups, each with its',
             '     own frame (the element origin) and its own bounding box. -->',
             '<robot name="demo_scara">']
    for link, elements in scara_elements().items():
        lines.append(f'  <link name="{link}">')
        for element, _, xyz, rpy in elements:
            origin = f'<origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>'
            geometry = f'<geometry><mesh filename="{_mesh_uri(link + "_" + element)}"/></geometry>'
            lines += [f'    <visual name="{element}">{origin}{geometry}</visual>',
                      f'    <collision name="{element}">{origin}{geometry}</collision>']
        lines.append('  </link>')
    for name, kind, parent, child, xyz, axis, (lower, upper) in SCARA_JOINTS:
        lines += [f'  <joint name="{name}" type="{kind}">',
                  f'    <parent link="{parent}"/>',
                  f'    <child link="{child}"/>',
                  f'    <origin xyz="{_fmt(xyz)}" rpy="0.0 0.0 0.0"/>',
                  f'    <axis xyz="{_fmt(axis)}"/>',
                  f'    <limit lower="{lower!r}" upper="{upper!r}" effort="100.0" '
                  'velocity="1.0"/>',
                  '  </joint>']
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def scene_yaml() -> str:
    """Return the demo scene (format of ``collision_sensor.model.scene``)."""
    pose = f'{{xyz: [{_fmt(WASHER_XYZ).replace(" ", ", ")}], rpy: [0.0, 0.0, 0.0]}}'
    lines = ['# Generated by "python -m collision_sensor.tools.demo_cell"; edit that, not this.',
             '# The washer of the paper\'s application, in front of the demo arm. All washer',
             '# parts share one frame: origin at the bottom centre of the front face, x into the',
             '# machine.',
             'objects:']
    for name, what in (('washer_cabinet', 'shell with the porthole in the front panel'),
                       ('washer_drum', 'hollow drum open towards the door'),
                       ('washer_door', 'door, open on its hinge')):
        lines += [f'  - name: {name:<16}# {what}',
                  f'    mesh: {{filename: ../meshes/{MESH_SUBDIR}/{name}.stl}}',
                  f'    pose: {pose}']
    size = ', '.join(repr(v) for v in FLOOR_SIZE)
    xyz = ', '.join(repr(v) for v in FLOOR_XYZ)
    lines += [f'  - name: {"floor":<16}# top face 2 mm below the arm\'s base',
              f'    box: {{size: [{size}]}}',
              f'    pose: {{xyz: [{xyz}], rpy: [0.0, 0.0, 0.0]}}']
    return '\n'.join(lines) + '\n'


def write_stl(mesh: trimesh.Trimesh, path: str, name: str) -> None:
    """Write ``mesh`` as binary STL with stable bytes (fixed header, normals from vertices)."""
    triangles = np.round(mesh.vertices[mesh.faces], VERTEX_DECIMALS).astype(np.float32)
    t64 = triangles.astype(np.float64)
    normals = np.cross(t64[:, 1] - t64[:, 0], t64[:, 2] - t64[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = (normals / np.where(lengths > 0.0, lengths, 1.0)).astype(np.float32)
    record = np.zeros(len(triangles), dtype=[('normal', '<f4', 3), ('vertices', '<f4', (3, 3)),
                                              ('attribute', '<u2')])
    record['normal'] = normals
    record['vertices'] = triangles
    header = f'collision_sensor demo_cell {name}'.encode('ascii')[:80].ljust(80, b' ')
    with open(path, 'wb') as stream:
        stream.write(header)
        stream.write(struct.pack('<I', len(triangles)))
        stream.write(record.tobytes())


def all_meshes() -> Dict[str, trimesh.Trimesh]:
    """Return every mesh file's mesh by its file stem (``arm_<link>``, ``washer_*``, ...)."""
    meshes = {f'arm_{link}': mesh for link, mesh in arm_link_meshes().items()}
    meshes.update(washer_meshes())
    for link, elements in scara_elements().items():
        for element, mesh, _, _ in elements:
            meshes[f'{link}_{element}'] = mesh
    return meshes


# === sequences =================================================================================

def _path(start, moves, rate=SEQUENCE_RATE) -> JointSequence:
    """Sample a path of moves at ``rate`` Hz.

    Each move runs through its poses in order, linearly in joint space between them, timed
    with a minimum-jerk profile over the whole move (at rest at both ends).
    :param start: (6,) the first frame.
    :param moves: [(duration s, [(6,) pose, ...])].
    """
    rows, times = [np.asarray(start, dtype=float)], [0.0]
    for duration, poses in moves:
        knots = np.vstack([rows[-1]] + [np.asarray(p, dtype=float) for p in poses])
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(knots, axis=0), axis=1))])
        steps = max(1, int(round(duration * rate)))
        for k in range(1, steps + 1):
            s = k / steps
            along = arc[-1] * s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
            rows.append(np.array([np.interp(along, arc, knots[:, j])
                                  for j in range(knots.shape[1])]))
            times.append(len(times) / rate)
    return JointSequence(ARM_JOINT_NAMES, np.round(times, SEQUENCE_DECIMALS),
                         np.round(rows, SEQUENCE_DECIMALS) + 0.0, 'demo_cell')


HOME = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
SHOULDER_HEIGHT = 0.19 + 0.26     # the shoulder_lift axis above the floor
UPPER_ARM = 0.45
PORTHOLE = (WASHER_XYZ[0] + WALL / 2.0, HOLE_Z)   # (x, z) of the porthole centre, world


def _aim(lift, target, pan=0.0, wrist_pitch=0.0, tool_roll=0.0):
    """Return the pose with ``shoulder_lift = lift`` and the forearm pointing at ``target``.

    The arm moves in the vertical plane turned by ``pan``; ``target`` is (distance from the
    base axis, height) in that plane. With the wrist straight, forearm, wrist and tool all lie
    on the line from the elbow through the target: a pose series with rising ``lift`` pushes
    the tool along that line, through the porthole when the target is its centre.
    """
    elbow_x = UPPER_ARM * math.sin(lift)
    elbow_z = SHOULDER_HEIGHT + UPPER_ARM * math.cos(lift)
    # forearm direction in the plane is (cos(lift + elbow), -sin(lift + elbow))
    downward = math.atan2(elbow_z - target[1], target[0] - elbow_x)
    return (pan, lift, downward - lift, 0.0, wrist_pitch, tool_roll)


def _insert(lifts, target, **kwargs):
    return [_aim(lift, target, **kwargs) for lift in lifts]


def paper_experiment() -> JointSequence:
    """The paper's experiment: a path that drives the arm into the machine.

    The arm aims above the porthole, strikes the front panel and pushes on into it, backs off,
    enters the drum through the door and swings sideways into the porthole's rim and the drum
    wall, then withdraws home.
    """
    too_high = (PORTHOLE[0], HOLE_Z + HOLE_RADIUS + 0.09)
    deep = _aim(1.35, PORTHOLE)
    return _path(HOME, [
        (1.2, [_aim(0.15, too_high)]),
        (1.4, _insert(np.linspace(0.15, 0.75, 7)[1:], too_high)),    # into the front panel
        (1.2, _insert(np.linspace(0.75, 0.15, 7)[1:], too_high)),    # back off
        (0.8, [_aim(0.35, PORTHOLE)]),
        (1.6, _insert(np.linspace(0.35, 1.35, 11)[1:], PORTHOLE)),   # through the porthole
        (1.4, [(0.32,) + deep[1:]]),                                 # swing into the rim
        (1.0, [deep]),
        (1.6, _insert(np.linspace(1.35, 0.35, 11)[1:], PORTHOLE)),
        (1.2, [HOME]),
    ])


def into_drum_clear() -> JointSequence:
    """A path into the drum through the open door that touches nothing.

    Every link stays clear of every part at every frame, yet the forearm, wrist and tool sit
    inside the cabinet's and the drum's bounding boxes: a box-level answer reports contact.
    """
    deep = 1.35
    return _path(HOME, [
        (1.2, [_aim(0.35, PORTHOLE)]),
        (1.8, _insert(np.linspace(0.35, deep, 11)[1:], PORTHOLE)),
        (0.8, [_aim(deep, PORTHOLE, pan=0.04, wrist_pitch=0.15, tool_roll=1.5)]),
        (0.8, [_aim(deep, PORTHOLE, pan=-0.04, wrist_pitch=-0.15, tool_roll=-1.5)]),
        (0.6, [_aim(deep, PORTHOLE)]),
        (1.8, _insert(np.linspace(deep, 0.35, 11)[1:], PORTHOLE)),
        (1.2, [HOME]),
    ])


def random_configurations(count: int = 300, seed: int = 1998, rate: float = 10.0):
    """Random configurations within the joint limits, no coherence between frames."""
    rng = np.random.default_rng(seed)
    lower = np.array([joint[5][0] for joint in ARM_JOINTS])
    upper = np.array([joint[5][1] for joint in ARM_JOINTS])
    positions = rng.uniform(lower, upper, size=(count, len(lower)))
    times = np.arange(count) / rate
    return JointSequence(ARM_JOINT_NAMES, np.round(times, SEQUENCE_DECIMALS),
                         np.round(positions, SEQUENCE_DECIMALS) + 0.0, 'demo_cell')


# --- the dynamic scene: a part on a conveyor, picked up, carried, dropped; a fixture --------

CRATE_SIZE = 0.12
CRATE_IN_TOOL = (0.20, 0.0, 0.0)   # the crate's centre in the tool frame, once picked up
FIXTURE = (0.10, 1.2)              # diameter and length of the post that appears


def _tool_pose(q) -> np.ndarray:
    """(4, 4) pose of tool_link for the arm's joint values ``q`` (ARM_JOINTS, no rpy)."""
    T = np.eye(4)
    for (_, _, _, xyz, axis, _), value in zip(ARM_JOINTS, q):
        step = np.eye(4)
        step[:3, 3] = xyz
        k = np.asarray(axis, dtype=float)
        K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        R = np.eye(4)
        R[:3, :3] = np.eye(3) + math.sin(value) * K + (1.0 - math.cos(value)) * K @ K
        T = T @ step @ R
    return T


def _scene_marker(ns, kind=1, action=0, frame='', T=None, scale=(1.0, 1.0, 1.0), text=''):
    """A marker of the node's scene topic (visualization_msgs/Marker's fields; kind 1 CUBE,
    3 CYLINDER; action 0 ADD, 3 DELETEALL)."""
    from types import SimpleNamespace as Fields
    T = np.eye(4) if T is None else T
    w = math.sqrt(max(0.0, 1.0 + T[0, 0] + T[1, 1] + T[2, 2])) / 2.0
    if w > 1e-6:
        x, y, z = ((T[2, 1] - T[1, 2]) / (4 * w), (T[0, 2] - T[2, 0]) / (4 * w),
                   (T[1, 0] - T[0, 1]) / (4 * w))
    else:   # a half turn: about the axis of the largest diagonal entry
        i = int(np.argmax(np.diag(T)[:3]))
        x, y, z = [math.sqrt(max(0.0, (1.0 + T[i, i]) / 2.0)) if j == i else
                   T[i, j] / (2.0 * math.sqrt(max(1e-300, (1.0 + T[i, i]) / 2.0)))
                   for j in range(3)]
    values = [round(float(v), SEQUENCE_DECIMALS) + 0.0 for v in (*T[:3, 3], x, y, z, w)]
    return Fields(
        header=Fields(frame_id=frame), ns=ns, id=0, type=kind, action=action,
        pose=Fields(position=Fields(x=values[0], y=values[1], z=values[2]),
                    orientation=Fields(x=values[3], y=values[4], z=values[5], w=values[6])),
        scale=Fields(x=scale[0], y=scale[1], z=scale[2]), points=(), mesh_resource='',
        text=text)


def moving_part() -> JointSequence:
    """The paper's dynamic scene: objects that move by command or by being attached.

    A crate comes along a conveyor into the tool (contact with the world object), is picked
    up (attached to tool_link, touching wrist_pitch_link: that contact is no longer checked,
    while the crate in the hand touches the washer's top), carried aside and lowered, dropped
    there (a world object again), and removed; a fixture appears in the arm's way home (contact)
    and is moved away.
    """
    from collision_sensor.model.sequences import SceneEvent
    crate = (CRATE_SIZE,) * 3
    cabinet_x = WASHER_XYZ[0] - 0.05     # the crate's centre on the conveyor, at the washer

    def place(xyz):
        T = np.eye(4)
        T[:3, 3] = xyz
        return T

    aside = (-1.4, 0.0, 0.0, 0.0, 0.0, 0.0)
    lowered = (-1.4, 0.9, 0.4, 0.0, -0.3, 0.0)
    seq = _path(HOME, [(2.4, [HOME]), (2.0, [aside]), (1.6, [lowered]), (0.2, [lowered]),
                       (1.2, [aside]), (2.0, [HOME]), (0.6, [HOME])])
    held = place(CRATE_IN_TOOL)
    events = [SceneEvent(0.1 * k, (_scene_marker('crate', T=place(
        (cabinet_x, 0.9 * (1.0 - k / 20.0), _tool_pose(HOME)[2, 3])), scale=crate),))
        for k in range(21)]
    events.append(SceneEvent(2.4, (_scene_marker('crate', frame='tool_link', T=held,
                                                 scale=crate, text='wrist_pitch_link'),)))
    drop = 2.4 + 2.0 + 1.6 + 0.2
    events.append(SceneEvent(drop, (_scene_marker('crate', T=_tool_pose(lowered) @ held,
                                                  scale=crate),)))
    home_start = drop + 1.2
    post = dict(kind=3, scale=(FIXTURE[0], FIXTURE[0], FIXTURE[1]))
    events.append(SceneEvent(home_start, (_scene_marker(
        'fixture', T=place((0.25, -0.25, FIXTURE[1] / 2)), **post),)))
    events.append(SceneEvent(home_start + 1.4, (_scene_marker(
        'fixture', T=place((0.25, -0.9, FIXTURE[1] / 2)), **post),)))
    events.append(SceneEvent(float(seq.times[-1]) - 0.2, (_scene_marker('', action=3),)))
    return JointSequence(seq.joint_names, seq.times, seq.positions, seq.source, tuple(events))


def bundled_sequences() -> Dict[str, JointSequence]:
    """Return the bundled sequences by file stem."""
    return {'paper_experiment': paper_experiment(), 'into_drum_clear': into_drum_clear(),
            'random': random_configurations()}


_SEQUENCE_NOTES = {
    'paper_experiment': 'the paper\'s experiment: the arm is driven into the washer (collides)',
    'into_drum_clear': 'into the drum through the open door; collision-free at every frame, '
                       'in contact at box level',
    'random': 'random configurations within the joint limits (seed 1998), no coherence',
}


# === writing ===================================================================================

def default_output_dir() -> str:
    """Return the source tree's root (the directory holding ``config/`` and ``meshes/``)."""
    return SOURCE_ROOT


def generate(output_dir: Optional[str] = None) -> list:
    """Write every demo-cell file under ``output_dir``; return the paths written (sorted)."""
    root = output_dir or default_output_dir()
    mesh_dir = os.path.join(root, 'meshes', MESH_SUBDIR)
    config_dir = os.path.join(root, 'config')
    sequence_dir = os.path.join(config_dir, 'sequences')
    for directory in (mesh_dir, sequence_dir):
        os.makedirs(directory, exist_ok=True)
    written = []
    for name, mesh in sorted(all_meshes().items()):
        path = os.path.join(mesh_dir, name + '.stl')
        write_stl(mesh, path, name)
        written.append(path)
    for name, text in (('demo_arm.urdf', arm_urdf()), ('demo_arm.srdf', arm_srdf()),
                       ('scara.urdf', scara_urdf()), ('demo_scene.yaml', scene_yaml())):
        path = os.path.join(config_dir, name)
        with open(path, 'w', encoding='utf-8', newline='\n') as stream:
            stream.write(text)
        written.append(path)
    for name, seq in bundled_sequences().items():
        path = os.path.join(sequence_dir, name + '.csv')
        write_sequence(seq, path)
        with open(path, encoding='utf-8') as stream:
            body = stream.read()
        with open(path, 'w', encoding='utf-8', newline='\n') as stream:
            stream.write(f'# {_SEQUENCE_NOTES[name]}\n'
                         '# generated by "python -m collision_sensor.tools.demo_cell"; time in s, '
                         'joints in rad\n' + body)
        written.append(path)
    for name, seq in (('paper_experiment', paper_experiment()), ('moving_part', moving_part())):
        bag = os.path.join(sequence_dir, name)
        if os.path.isdir(bag):
            shutil.rmtree(bag)
        write_sequence(seq, bag, fmt='mcap')
        written += [os.path.join(bag, entry) for entry in sorted(os.listdir(bag))]
    return sorted(written)


def main(argv=None) -> int:
    """Regenerate the demo cell files (deterministic)."""
    parser = argparse.ArgumentParser(
        prog='python -m collision_sensor.tools.demo_cell',
        description='Write the demo cell: meshes, URDFs, SRDF, scene and bundled sequences.')
    parser.add_argument('--output-dir', default=None,
                        help='root to write config/ and meshes/ under (default: this source '
                             'tree, %(default)s)')
    args = parser.parse_args(argv)
    for path in generate(args.output_dir):
        print(path)
    return 0


if __name__ == '__main__':
    sys.exit(main())
