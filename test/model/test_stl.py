"""collision_sensor.model.stl against trimesh, the loader it replaces for STL files."""
import glob
import os

import numpy as np
import pytest
import trimesh

from collision_sensor.model.example_robots import example_robot_data_dir
from collision_sensor.model.stl import StlError, merge_vertices, read_stl


def _corners(vertices, faces):
    return np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]


@pytest.mark.slow
def test_every_example_robot_stl_reads_as_trimesh_reads_it():
    files = sorted(glob.glob(os.path.join(example_robot_data_dir(), 'robots', '**', '*.stl'),
                             recursive=True))
    assert len(files) > 100
    for path in files[::3]:  # a third of them keeps the test short; every robot is in it
        vertices, faces = read_stl(path)
        mesh = trimesh.load(path, force='mesh')
        ours, theirs = _corners(vertices, faces), _corners(mesh.vertices, mesh.faces)
        assert ours.shape == theirs.shape, path
        # trimesh merges vertices closer than 1e-8; the files are float32, so the corners of
        # the two readings are the same points to far below that.
        assert np.allclose(ours, theirs, rtol=0, atol=1e-7), path


def test_ascii_and_binary_files_of_one_mesh_read_alike(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    binary, ascii_ = tmp_path / 'a.stl', tmp_path / 'b.stl'
    binary.write_bytes(trimesh.exchange.stl.export_stl(mesh))
    ascii_.write_text(trimesh.exchange.stl.export_stl_ascii(mesh))
    vb, fb = read_stl(str(binary))
    va, fa = read_stl(str(ascii_))
    assert len(vb) == len(mesh.vertices) and len(fb) == len(mesh.faces)
    assert np.allclose(_corners(vb, fb), _corners(mesh.vertices, mesh.faces), atol=1e-6)
    assert np.allclose(_corners(va, fa), _corners(mesh.vertices, mesh.faces), atol=1e-6)
    assert vb.dtype == np.float64 and fb.dtype == np.int64


def test_broken_files_are_errors_saying_why(tmp_path):
    good = trimesh.exchange.stl.export_stl(trimesh.creation.box())
    truncated = tmp_path / 'truncated.stl'
    truncated.write_bytes(good[:-7])
    with pytest.raises(StlError, match='neither a binary STL'):
        read_stl(str(truncated))
    odd = tmp_path / 'odd.stl'
    odd.write_text('solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n'
                   'endloop\nendfacet\nendsolid x\n')
    with pytest.raises(StlError, match='not three per facet'):
        read_stl(str(odd))
    words = tmp_path / 'words.stl'
    words.write_text('solid x\nvertex 0 0 zero\nvertex 1 0 0\nvertex 0 1 0\nendsolid x\n')
    with pytest.raises(StlError, match='not three numbers'):
        read_stl(str(words))


def _merged_by_dict(corners):
    """The oracle: equal corners (by value: -0.0 is 0.0) become one vertex, numbered as first
    seen."""
    index, vertices, faces = {}, [], []
    for corner in corners:
        key = tuple(float(x) + 0.0 for x in corner)
        if key not in index:
            index[key] = len(vertices)
            vertices.append(key)
        faces.append(index[key])
    return np.array(vertices), np.array(faces).reshape(-1, 3)


def _assert_merged_as_the_oracle(corners):
    vertices, faces = merge_vertices(corners)
    expected_vertices, expected_faces = _merged_by_dict(corners)
    assert np.array_equal(vertices, expected_vertices)
    assert np.array_equal(faces, expected_faces)
    assert faces.dtype == np.int64


def test_vertices_merge_as_a_dictionary_merges_them():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(500, 3))
    # sign patterns that cancel in a weak hash, zeros of both signs, repeats far apart
    mirrored = np.concatenate([points, -points, points * [-1, -1, 1], points * [1, -1, -1]])
    mirrored[:50, 0] = 0.0
    mirrored[50:100, 0] = -0.0
    corners = mirrored[rng.integers(0, len(mirrored), 3 * 4000)]
    _assert_merged_as_the_oracle(corners)
    _assert_merged_as_the_oracle(np.repeat(points[:1], 6, axis=0))     # one vertex
    _assert_merged_as_the_oracle(points[:300])                          # none shared


def test_unequal_corners_of_one_hash_are_kept_apart(monkeypatch):
    """Every corner given the same hash: the merge must still keep unequal ones apart."""
    from collision_sensor.model import stl
    monkeypatch.setattr(stl, '_HASH_WORDS', np.zeros(3, dtype=np.uint64))
    rng = np.random.default_rng(4)
    points = rng.normal(size=(40, 3))
    _assert_merged_as_the_oracle(points[rng.integers(0, 40, 3 * 100)])


def test_the_so101_wrist_merges_as_a_dictionary_merges_it(monkeypatch):
    """The largest STL of example-robot-data (161,982 corners), mirrored halves and all."""
    from collision_sensor.model import stl
    path = os.path.join(example_robot_data_dir(), 'robots', 'so_arm_description', 'meshes',
                        'so101', 'wrist_roll_pitch_so101_v2.stl')
    read = []
    monkeypatch.setattr(stl, 'merge_vertices', lambda corners: read.append(corners) or (
        np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)))
    read_stl(path)
    monkeypatch.undo()
    assert len(read[0]) > 150000
    _assert_merged_as_the_oracle(read[0])
