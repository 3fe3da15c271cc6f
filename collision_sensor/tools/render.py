"""Draw the README pictures: the demo cell at one frame, and a sequence's contact timeline.

``python -m collision_sensor.tools.render`` writes both into ``meshes/readme/``:

``cell.png``
    The demo arm and the washer from the meshes (matplotlib, Agg, ``Poly3DCollection``), the
    arm at one frame of the paper's experiment (default ``--time 2.6`` s, when the tool is in
    the drum and the wrist touches the porthole), every link's root box
    (:meth:`CollisionChecker.collision_boxes`) as a wireframe, colliding links and their boxes
    in red, washer parts in contact tinted orange.
``timeline.png``
    ``collision_sensor_check paper_experiment --plot timeline.png``.

Flat shading from one light. Matplotlib sorts triangles by depth only within one collection
(painter's algorithm), so the picture is drawn in layers: the floor, the see-through washer,
the arm over it (the links in the drum stay visible), the box wireframes on top.
"""
import argparse
import contextlib
import io
import os
import sys
from typing import List, Optional, Sequence, Tuple

import numpy as np

PROG = 'python -m collision_sensor.tools.render'
DEFAULT_SEQUENCE = 'paper_experiment'
DEFAULT_TIME = 2.6          # s from the first frame: tool in the drum, wrist at the porthole

#: RGBA of each kind of surface: arm, arm in collision, scene, scene in contact, floor.
ARM_RGBA = (0.62, 0.66, 0.72, 1.0)
HIT_RGBA = (0.86, 0.10, 0.10, 1.0)
SCENE_RGBA = (0.55, 0.62, 0.80, 0.12)
SCENE_HIT_RGBA = (1.00, 0.55, 0.10, 0.16)
FLOOR_RGBA = (0.80, 0.80, 0.78, 0.35)
BOX_RGB, BOX_HIT_RGB = (0.10, 0.45, 0.20), (0.85, 0.0, 0.0)
LIGHT = np.array([-0.4, -0.6, 0.7]) / np.linalg.norm([-0.4, -0.6, 0.7])
AMBIENT = 0.45              # share of the colour that does not depend on the light
VIEW = {'elev': 25.0, 'azim': -125.0}   # from the front left: into the porthole
#: Half of the drawn floor (m), around the arm and the washer, not the 2 m scene object.
FLOOR_XY = ((-0.3, 1.4), (-0.5, 0.4))

#: The 12 edges of a box, as pairs of corner indices; corner k has the sign of bit i of k on
#: axis i.
_BOX_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count('1') == 1]


def demo_checker():
    """Return the checker of the bundled demo cell (arm, SRDF, washer scene)."""
    from collision_sensor import CollisionChecker
    from collision_sensor.model.share import config_path
    return CollisionChecker.from_urdf(config_path('demo_arm.urdf'),
                                      srdf=config_path('demo_arm.srdf'),
                                      scene=config_path('demo_scene.yaml'))


def box_corners(T_world_box: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Return the 8 corners (8, 3) of a box; corner k is at ``+-half[i]`` by bit i of k."""
    signs = np.array([[1.0 if k >> i & 1 else -1.0 for i in range(3)] for k in range(8)])
    return (signs * half) @ T_world_box[:3, :3].T + T_world_box[:3, 3]


def shaded(rgba: Sequence[float], triangles: np.ndarray) -> np.ndarray:
    """Return one RGBA (m, 4) per triangle (m, 3, 3): ``rgba`` lit by :data:`LIGHT`.

    Two-sided: a face lit from behind is shaded as if it faced the light (meshes of the washer
    are seen from inside too).
    """
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    lengths[lengths == 0.0] = 1.0
    light = np.abs(normals @ LIGHT) / lengths
    colors = np.tile(np.asarray(rgba, dtype=float), (len(triangles), 1))
    colors[:, :3] *= (AMBIENT + (1.0 - AMBIENT) * light)[:, None]
    return colors


def world_triangles(checker) -> List[Tuple[str, str, np.ndarray]]:
    """Return ``(body, kind, triangles (m, 3, 3))`` of every link and scene object at the
    checker's last state; ``kind`` is ``"link"`` or ``"scene"``.
    """
    from collision_sensor.model.scene import load_scene
    from collision_sensor.model.share import config_path

    poses = checker.link_poses()
    bodies = []
    for element in checker.model.elements:
        T = poses[element.link] @ element.T_link_element
        vertices = element.vertices @ T[:3, :3].T + T[:3, 3]
        bodies.append((element.link, 'link', vertices[element.faces]))
    for obj in load_scene(config_path('demo_scene.yaml')):
        if obj.name == 'floor':
            continue    # drawn as a patch of FLOOR_XY: the whole 2 m box only shrinks the arm
        T = obj.T_world_object
        vertices = obj.vertices @ T[:3, :3].T + T[:3, 3]
        bodies.append((obj.name, 'scene', vertices[obj.faces]))
    return bodies


def render_cell(checker, positions: np.ndarray, path: str, title: str = '',
                dpi: int = 100) -> Tuple[Tuple[str, str], ...]:
    """Draw the cell at ``positions`` (checked from scratch) to the PNG ``path``.

    :param positions: (J,) float joint positions in ``checker.joint_names`` order.
    :return: the colliding pairs drawn.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    result = checker.check(positions)
    pairs = tuple(result.colliding_pairs)
    touched = {name for pair in pairs for name in pair}

    # Three layers, drawn in this order: the floor, the see-through washer, the arm. The arm
    # is drawn over the washer (not depth-sorted with it) so that the links in the drum stay
    # visible; within a layer matplotlib sorts the triangles by depth.
    layers = {'scene': ([], []), 'link': ([], [])}
    for body, kind, tris in world_triangles(checker):
        if kind == 'link':
            rgba = HIT_RGBA if body in touched else ARM_RGBA
        else:
            rgba = SCENE_HIT_RGBA if body in touched else SCENE_RGBA
        layers[kind][0].append(tris)
        layers[kind][1].append(shaded(rgba, tris))
    (x0, x1), (y0, y1) = FLOOR_XY
    floor = np.array([[[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0]],
                      [[x0, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]]]) - [0.0, 0.0, 0.002]
    layers = [(floor, np.array([FLOOR_RGBA, FLOOR_RGBA]))] + [
        (np.concatenate(tris), np.concatenate(colors)) for tris, colors in layers.values()]

    edges, edge_colors = [], []
    for name, T_world_box, half in checker.collision_boxes(checker.link_names):
        corners = box_corners(T_world_box, half)
        color = BOX_HIT_RGB if name in touched else BOX_RGB
        edges += [corners[[a, b]] for a, b in _BOX_EDGES]
        edge_colors += [color] * len(_BOX_EDGES)

    fig = plt.figure(figsize=(8.0, 6.0))
    try:
        ax = fig.add_subplot(projection='3d', computed_zorder=False)
        for zorder, (triangles, colors) in enumerate(layers):
            ax.add_collection3d(Poly3DCollection(triangles, facecolors=colors,
                                                 edgecolors='none', linewidths=0.0,
                                                 antialiased=False, zorder=zorder))
        ax.add_collection3d(Line3DCollection(edges, colors=edge_colors, linewidths=0.9,
                                             zorder=len(layers)))
        points = np.concatenate([triangles.reshape(-1, 3) for triangles, _ in layers])
        low, high = points.min(axis=0), points.max(axis=0)
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(low[1], high[1])
        ax.set_zlim(low[2], high[2])
        ax.set_box_aspect(high - low, zoom=1.3)
        ax.view_init(**VIEW)
        ax.set_axis_off()
        legend = [Patch(facecolor=ARM_RGBA, label='arm link'),
                  Patch(facecolor=HIT_RGBA, label='link in collision'),
                  Patch(facecolor=SCENE_HIT_RGBA[:3] + (0.6,), label='washer part in contact'),
                  Line2D([], [], color=BOX_RGB, label='root box of a link'),
                  Line2D([], [], color=BOX_HIT_RGB, label='root box, link in collision')]
        ax.legend(handles=legend, loc='lower right', bbox_to_anchor=(0.99, 0.02), fontsize=9,
                  frameon=False)
        text = title + ('\n' if title else '') + (
            'colliding: ' + ', '.join(f'{a} -- {b}' for a, b in pairs) if pairs
            else 'no collision')
        fig.text(0.5, 0.965, text, ha='center', va='top', fontsize=10, wrap=True)
        fig.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=1.0)
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)
    return pairs


def frame_at(seq, seconds: float) -> int:
    """Return the index of the frame nearest ``seconds`` after the first frame."""
    return int(np.argmin(np.abs(seq.times - seq.times[0] - seconds)))


def readme_directory() -> str:
    """Return ``meshes/readme`` of the package (the README's pictures)."""
    from collision_sensor.model.share import mesh_directory
    return os.path.join(mesh_directory(), 'readme')


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Write ``cell.png`` and ``timeline.png``; return the exit status (0, or 2 on an error)."""
    parser = argparse.ArgumentParser(
        prog=PROG, description='Draw the README pictures of the demo cell: cell.png (the cell '
                               'at one frame) and timeline.png (contacts over the sequence).')
    parser.add_argument('--sequence', default=DEFAULT_SEQUENCE, metavar='NAME|PATH',
                        help='bundled sequence or file (default %(default)s)')
    parser.add_argument('--time', type=float, default=DEFAULT_TIME, metavar='S',
                        help='the frame drawn in cell.png, seconds from the first frame '
                             '(default %(default)g)')
    parser.add_argument('--out', metavar='DIR', help='output directory (default meshes/readme)')
    args = parser.parse_args(argv)

    from collision_sensor.errors import CollisionSensorError
    from collision_sensor.model.sequences import read_sequence
    from collision_sensor.tools import offline_check

    out = args.out or readme_directory()
    os.makedirs(out, exist_ok=True)
    try:
        checker = demo_checker()
        seq = read_sequence(offline_check.bundled_sequence_path(args.sequence),
                            joint_names=checker.joint_names)
    except CollisionSensorError as err:
        print(f'{PROG}: error: {err}', file=sys.stderr)
        return 2
    index = frame_at(seq, args.time)
    t = float(seq.times[index] - seq.times[0])
    cell = os.path.join(out, 'cell.png')
    pairs = render_cell(checker, seq.positions[index], cell,
                        title=f'{os.path.basename(seq.source)}, frame {index} (t = {t:.2f} s)')
    print(f'{cell}: frame {index}, t = {t:.2f} s, {len(pairs)} colliding pairs')

    timeline = os.path.join(out, 'timeline.png')
    with contextlib.redirect_stdout(io.StringIO()):
        status = offline_check.main([seq.source, '--plot', timeline, '--progress', 'never'])
    if status == offline_check.EXIT_ERROR:
        return 2
    print(f'{timeline}: contacts of {os.path.basename(seq.source)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
