"""Scenario 8: proximity (``CollisionChecker.proximity``) against python-fcl and pinocchio+coal.

Per robot (Panda, UR5, each with its SRDF; or the user's robot, ``python -m benchmarks
--urdf``), the same seeded random configurations go to:

- ours, ``proximity(q, inf)``: FK, the collision query, then every checked pair's distance and
  nearest points (the same work as the peers: every pair measured);
- ours, ``proximity(q, MAX_DISTANCE)``: only pairs nearer than 0.1 m are measured (the use the
  API is made for; the peers have no such cut-off);
- python-fcl: one ``fcl.distance`` per element pair of every checked pair (BVHs, OBBRSS, over
  the triangles our loader produced), placed with our kinematics' poses (FK not counted: the
  poses are computed before timing);
- pinocchio+coal: ``computeDistances`` (its FK, placements and the geometry pairs of exactly
  our checked link pairs), its own URDF and mesh loading.

The agreement column compares, per configuration, the smallest distance over the pairs that
do not collide, ours against python-fcl's on the same triangles (within 1e-6 m).

The warning zone's cost, as the node pays it per joint state: along a seeded random walk
(every joint moves by N(0, WALK_STEP) rad or m per state, kept within the limits), ``update``
alone against ``update`` then ``proximity(q, WARNING_DISTANCE)``; each pass starts from the
walk's first state after a full check (untimed).
"""
import math
from typing import Dict, List

import numpy as np

from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from benchmarks.robot_peers import stream
from benchmarks.scenario_cells import robot_cell
from benchmarks.scenario_measure import Candidate, interleaved_us
from benchmarks.scenario_peers import optional_peer, pinocchio_peer
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 8: proximity (distances and nearest points) against python-fcl and pinocchio'
TARGET_RATIO = 0.5
MAX_DISTANCE = 0.1
AGREEMENT_TOLERANCE = 1e-6
WARNING_DISTANCE = 0.05     # m, the node's warning_distance in the warning-zone measurement
WALK_STEP = 0.002           # rad or m per joint and state
WALK_STATES = 3000


class FclDistances:
    """python-fcl on the checker's elements: every checked pair's distance."""

    def __init__(self, checker):
        """:raises ImportError: python-fcl is not installed."""
        import fcl
        from benchmarks.scenario_peers import fcl_bvh
        self.fcl = fcl
        self.objects: Dict[str, list] = {}
        for element in checker.model.elements:
            T = element.T_link_element
            vertices = element.vertices @ T[:3, :3].T + T[:3, 3]
            self.objects.setdefault(element.link, []).append(
                fcl.CollisionObject(fcl_bvh(vertices, element.faces)))
        self.pairs = [(self.objects[a], self.objects[b]) for a, b in checker.checked_pairs]
        self.request = fcl.DistanceRequest()

    def place(self, poses: Dict[str, np.ndarray]) -> None:
        for link, objects in self.objects.items():
            T = poses[link]
            transform = self.fcl.Transform(T[:3, :3], T[:3, 3])
            for obj in objects:
                obj.setTransform(transform)

    def distances(self, poses: Dict[str, np.ndarray]) -> List[float]:
        """Place the links at ``poses``; return each checked pair's distance (fcl's value for
        colliding meshes, -1 or 0)."""
        self.place(poses)
        distance, request, Result = self.fcl.distance, self.request, self.fcl.DistanceResult
        return [min(distance(oa, ob, request, Result()) for oa in objects_a for ob in objects_b)
                for objects_a, objects_b in self.pairs]


def pinocchio_distance_peer(cell, checker):
    """pinocchio+coal on ``cell`` with our checked pairs; ``check(q)`` runs computeDistances.

    :raises ImportError: pinocchio is not installed.
    """
    peer = pinocchio_peer(cell, checker)
    pin = peer.pin

    def distances(q):
        return pin.computeDistances(peer.model, peer.data, peer.geom, peer.geom_data, q)
    peer.distances = distances
    return peer


def _agreement(checker, configurations, fcl_peer, poses) -> str:
    same = 0
    for q, P in zip(configurations, poses):
        records = checker.proximity(q, math.inf)
        ours = min((r.distance for r in records if r.distance > 0), default=math.inf)
        colliding = set(checker.check(q).colliding_pairs)
        theirs = min((d for pair, d in zip(checker.checked_pairs, fcl_peer.distances(P))
                      if pair not in colliding), default=math.inf)
        same += (ours == theirs == math.inf) or abs(ours - theirs) <= AGREEMENT_TOLERANCE
    return f'{same}/{len(configurations)}'


def run(settings, cells=None) -> Section:
    """Measure proximity on ``cells`` (default: the Panda and the UR5); return the section
    (target: ours, every pair measured, <= 0.5x python-fcl's distance calls on the same
    pairs)."""
    cells = cells or [robot_cell('panda'), robot_cell('ur5')]
    section = Section(8, TITLE)
    n = 30 if settings.quick else 300
    section.text(f'{n} seeded random configurations per robot; time per configuration, best '
                 f'of {settings.rounds} interleaved passes. "ours all" measures every checked '
                 f'pair (as the peers do), "ours < {MAX_DISTANCE:g} m" only pairs nearer than '
                 f'that; python-fcl without FK, ours and pinocchio with it.')
    rows = []
    for cell in cells:
        name = cell.name
        checker = cell.checker()
        configurations = list(random_configurations(checker, n, settings.seed))
        poses = []
        for q in configurations:
            checker.check(q)
            poses.append(checker.link_poses())
        candidates = [
            Candidate('ours all', lambda q: checker.proximity(q, math.inf), configurations),
            Candidate('ours near', lambda q: checker.proximity(q, MAX_DISTANCE), configurations)]
        fcl_peer, fcl_missing = optional_peer(FclDistances, checker)
        if fcl_peer is not None:
            candidates.append(Candidate('fcl', fcl_peer.distances, poses))
        pin, pin_missing = optional_peer(pinocchio_distance_peer, cell, checker)
        if pin is not None:
            pin_qs = [pin.configuration(checker, q) for q in configurations]
            candidates.append(Candidate('pinocchio', pin.distances, pin_qs))
        times = interleaved_us(candidates, settings.rounds)
        fcl_us, pin_us = times.get('fcl'), times.get('pinocchio')
        equal = (_agreement(checker, configurations, fcl_peer, poses) if fcl_peer is not None
                 else fcl_missing)
        rows.append([name, len(checker.checked_pairs), us(times['ours all']),
                     us(times['ours near']), us(fcl_us), us(pin_us),
                     ratio(times['ours all'], fcl_us), ratio(times['ours near'], fcl_us),
                     ratio(times['ours all'], pin_us), equal])
        section.judge_ratio(f'S8 {name}: proximity, every pair, <= 0.5x python-fcl distance',
                            times['ours all'], fcl_us, TARGET_RATIO, 'python-fcl', fcl_missing)
        section.judge_ratio(f'S8 {name}: proximity < {MAX_DISTANCE:g} m <= 0.5x python-fcl '
                            'distance (every pair)', times['ours near'], fcl_us, TARGET_RATIO,
                            'python-fcl', fcl_missing)
        if pin is None:
            section.text(f'{name}: pinocchio+coal {pin_missing}')
    section.table(['robot', 'pairs', 'ours all us', f'ours < {MAX_DISTANCE:g} m us',
                   'python-fcl us', 'pinocchio+coal us', 'all / fcl', 'near / fcl',
                   'all / pinocchio', 'min distance equal (fcl)'], rows)
    _warning_zone(section, settings, cells)
    return section


def _warning_zone(section, settings, cells):
    n = 300 if settings.quick else WALK_STATES
    rows = []
    for cell in cells:
        name = cell.name
        checker = cell.checker()
        walk = stream(checker, n, len(checker.joint_names), settings.seed, step=WALK_STEP,
                      bounds=sampling_bounds(checker))

        def zone(q, checker=checker):
            checker.update(q)
            return checker.proximity(q, WARNING_DISTANCE)

        def restart(checker=checker, first=walk[0]):
            checker.check(first)
        times = interleaved_us([Candidate('update', checker.update, walk, restart),
                                Candidate('zone', zone, walk, restart)], settings.rounds)
        rows.append([name, us(times['update']), us(times['zone']),
                     f'{times["zone"] / times["update"]:.0f}x'])
    section.text('', f'The warning zone as the node pays it per joint state: a seeded random walk '
                 f'of {n} states (each joint N(0, {WALK_STEP:g}) rad or m per state), `update` '
                 f'alone against `update` then `proximity(q, {WARNING_DISTANCE:g})` '
                 f'(`warning_distance: {WARNING_DISTANCE:g}`).')
    section.table(['robot', '`update` us', '`update` + `proximity` us', 'zone / update'],
                  rows)
