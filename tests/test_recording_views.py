"""The 3-D and text views of a recording, written by :class:`RerunWriter` and read back
with rerun's own reader, against the geometry they claim to draw: the string at minus
its measured depth with the lateral displacement exaggerated, the nodes on the wall, the
blades on the rays of the bit config's blade angles, each piece coloured by the rock the
formation's own lookup finds there, the interfaces between the rocks the scenario names.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drill_env.physics.bit import shoulder_lengths
from drill_env.physics.formation import rock_at
from drill_env.physics.simulator import Simulator
from drill_env.recording.recorder import capture_geometry
from drill_env.recording.replay import read_recording
from drill_env.recording.writer import RerunWriter, force_share, nice
from drill_env.scenarios import make_scenario

K = 50.0  # exaggeration of the lateral displacement in the string view
F32 = 1e-6  # rerun stores positions as float32: relative resolution ~6e-8, depths ~1e3 m


def _rows(path: Path) -> dict[str, list[dict[str, Any]]]:
    """Every row of every chunk, by entity, in file order; ``sim_time`` in seconds."""
    from rerun.chunk import RrdReader

    reader = RrdReader(str(path))
    rows: dict[str, list[dict[str, Any]]] = {}
    for chunk in reader.stream(store=reader.recordings()[0]):
        for row in chunk.to_record_batch().to_pylist():
            if "sim_time" in row:
                row["sim_time"] = row["sim_time"].total_seconds()
            rows.setdefault(chunk.entity_path, []).append(row)
    return rows


@pytest.fixture(scope="module")
def case2() -> tuple[Any, Any]:
    """Paper case 2 (hard - soft - hard, 45 deg dip): its simulator and scenario."""
    scenario = make_scenario("paper_case2")
    return Simulator(scenario.config), scenario


def _writer(path: Path, sim: Any, scenario: Any) -> tuple[Any, RerunWriter]:
    import rerun as rr

    stream = rr.RecordingStream("drill_env_test", recording_id=path.stem)
    stream.save(str(path))
    writer = RerunWriter(stream, capture_geometry(sim, scenario.config), K)
    return stream, writer


def test_the_string_is_drawn_at_minus_its_depth_and_only_nodes_with_a_wall_force_are_marked(
        tmp_path: Path, case2: tuple[Any, Any]) -> None:
    sim, scenario = case2
    path = tmp_path / "string.rrd"
    stream, writer = _writer(path, sim, scenario)
    depth_nodes = np.array(sim.node_depth, dtype=np.float64)
    n = len(depth_nodes)
    i = np.arange(n)
    lateral = [np.stack([1e-3 * np.sin(0.1 * i), -2e-3 * np.cos(0.05 * i)], axis=1),
               np.stack([-3e-3 * np.ones(n), 1e-4 * i / n], axis=1)]
    bit_depth = np.array([depth_nodes[-1], depth_nodes[-1] + 0.75])  # drilled 0.75 m on
    forces = [np.where(i % 3 == 0, 10.0 ** (2.0 + 3.0 * i / n), 0.0), np.zeros(n)]
    forces[1][-5:] = [0.0, 50.0, 1e3, 0.0, 4e4]
    times = np.array([0.5, 1.25])
    writer.string(times, lateral, bit_depth, forces)
    stream.flush()
    del stream, writer
    rows = _rows(path)

    strips = rows["/string/deflection"]
    assert [r["sim_time"] for r in strips] == pytest.approx(times, abs=1e-9)
    for row, xy, bit in zip(strips, lateral, bit_depth, strict=True):
        (points,) = row["LineStrips3D:strips"]
        points = np.array(points)
        np.testing.assert_allclose(points[:, :2], K * xy, rtol=F32, atol=1e-9)
        # z is minus the measured depth; the string moves down with the bit as it drills
        np.testing.assert_allclose(points[:, 2], -(depth_nodes + bit - depth_nodes[-1]),
                                   rtol=F32)
    bits = [np.array(r["Points3D:positions"][0]) for r in rows["/string/bit"]
            if "Points3D:positions" in r]
    for got, xy, bit in zip(bits, lateral, bit_depth, strict=True):
        np.testing.assert_allclose(got, [K * xy[-1, 0], K * xy[-1, 1], -bit], rtol=F32)

    contact = rows["/string/contact"]
    for row, xy, bit, force in zip(contact, lateral, bit_depth, forces, strict=True):
        on_wall = force > 0.0
        points = np.array(row["Points3D:positions"])
        assert len(points) == on_wall.sum()  # nodes without a wall force are not marked
        np.testing.assert_allclose(points[:, :2], K * xy[on_wall], rtol=F32, atol=1e-9)
        np.testing.assert_allclose(points[:, 2], -(depth_nodes[on_wall] + bit
                                                   - depth_nodes[-1]), rtol=F32)
        radii = np.array(row["Points3D:radii"])
        order = np.argsort(force[on_wall])
        assert np.all(np.diff(radii[order]) >= 0) and radii[order][-1] > radii[order][0]
        # colour (packed RGBA): the green channel falls from light yellow to dark red
        green = (np.array(row["Points3D:colors"], dtype=np.uint32) >> 16) & 0xFF
        assert np.all(np.diff(green[order].astype(int)) <= 0)
    assert force_share(np.array([50.0]))[0] == 0.0  # below the scale's 100 N: lightest


def test_the_blades_lie_on_the_config_blade_rays_and_each_piece_in_the_rock_it_is_coloured(
        tmp_path: Path, case2: tuple[Any, Any]) -> None:
    sim, scenario = case2
    cfg = scenario.config.bit
    formation = sim.formation
    path = tmp_path / "bit.rrd"
    stream, writer = _writer(path, sim, scenario)
    depth0 = float(sim.depth)
    itf = scenario.config.formation.interfaces
    # the bit face 0.12 m past the first interface's depth on the axis: with the 45 deg
    # dip the interface crosses the bit (hard on the +x side above it, soft below)
    states = np.array([[0.0, 0.0, depth0, 0.0],
                       [1.5e-3, -2.0e-3, itf[0].depth + 0.02, 0.7],
                       [-1.0e-3, 0.5e-3, itf[0].depth + 0.12, -2.0]])
    times = np.array([0.1, 0.2, 0.3])
    writer.blades(times, states)
    stream.flush()
    del stream, writer
    rows = _rows(path)

    alpha = math.radians(cfg.shoulder_angle)
    pad_radius = cfg.diameter / 2.0 - cfg.gauge_clearance
    blade_rows = [r for r in rows["/bit/blades"] if "LineStrips3D:strips" in r]
    assert [r["sim_time"] for r in blade_rows] == pytest.approx(times, abs=1e-9)
    rocks_seen = set()
    for row, (bx, by, depth, phi) in zip(blade_rows, states, strict=True):
        strips = np.array(row["LineStrips3D:strips"], dtype=np.float64)  # piece, end, xyz
        rock = np.array(row["LineStrips3D:class_ids"])
        rel = strips[:, :, :2] - [bx, by]
        radius = np.hypot(rel[..., 0], rel[..., 1])
        height = strips[:, :, 2] - (depth0 - depth)  # above the bit face
        assert radius.max() == pytest.approx(pad_radius, rel=1e-5)
        assert radius.min() == pytest.approx(min(cfg.face_start), abs=1e-5)
        top = shoulder_lengths(cfg)[0] * math.cos(alpha) + cfg.gauge_length[0]
        assert height.min() == pytest.approx(0.0, abs=1e-5)
        assert height.max() == pytest.approx(top, rel=1e-5)
        # every piece on the ray of one blade: angle = blade angle + bit rotation
        angle = np.arctan2(rel[..., 1], rel[..., 0])
        rays = np.radians(cfg.blade_angles) + phi
        off = np.abs(np.angle(np.exp(1j * (angle[..., None] - rays))))
        assert np.all(off.min(axis=-1) < 1e-4)
        assert {int(j) for j in off.min(axis=1).argmin(axis=-1)} == set(range(cfg.n_blades))
        # the colour of a piece is the rock at its midpoint (depth down = depth0 - z)
        mid = strips.mean(axis=1)
        for (x, y, z), r in zip(mid, rock, strict=True):
            assert r == rock_at(x, y, depth0 - z, formation.normals, formation.offsets,
                                formation.layer_rock)
        rocks_seen |= set(rock.tolist())
    assert rocks_seen == {0, 1}  # both rocks drawn: the interface cuts the bit

    texts = rows["/bit/blade_rocks"]
    first = texts[0]["TextDocument:text"][0]
    assert first.count("hard 100%") == cfg.n_blades and "soft" not in first
    assert len(texts) == 3  # the rocks under the blades changed at every snapshot
    assert "soft" in texts[1]["TextDocument:text"][0]


def test_front_share_text_counts_face_and_shoulder_not_the_gauge(
        tmp_path: Path, case2: tuple[Any, Any]) -> None:
    """With the face and shoulder in the soft layer and the +x gauge pad reaching up into
    the hard rock above the dipping interface, the text says soft 100 % for every blade."""
    sim, scenario = case2
    cfg = scenario.config.bit
    itf = scenario.config.formation.interfaces[0]
    formation = sim.formation
    alpha = math.radians(cfg.shoulder_angle)
    rise = shoulder_lengths(cfg)[0] * math.cos(alpha)
    pad = cfg.diameter / 2.0 - cfg.gauge_clearance
    depth = itf.depth + pad + rise + 0.01  # the shoulder's top at +x 1 cm below the plane
    top_of_pad = depth - rise - cfg.gauge_length[0]
    assert rock_at(pad, 0.0, top_of_pad, formation.normals, formation.offsets,
                   formation.layer_rock) == 0  # the pad's top is in the hard rock
    path = tmp_path / "share.rrd"
    stream, writer = _writer(path, sim, scenario)
    writer.blades(np.array([0.1]), np.array([[0.0, 0.0, depth, 0.0]]))
    stream.flush()
    del stream, writer
    text = _rows(path)["/bit/blade_rocks"][0]["TextDocument:text"][0]
    assert text.count("soft 100%") == cfg.n_blades, text


def test_the_interfaces_are_labelled_with_the_rocks_above_and_below_and_lie_on_the_plane(
        tmp_path: Path, case2: tuple[Any, Any]) -> None:
    sim, scenario = case2
    formation = sim.formation
    path = tmp_path / "scene.rrd"
    stream, writer = _writer(path, sim, scenario)
    writer.scene()
    stream.flush()
    del stream, writer
    (row,) = _rows(path)["/bit/interfaces"]
    labels = [x for x in row["LineStrips3D:labels"] if x]
    # the paper's case 2 sandwich: hard over soft over hard
    assert labels[0].startswith("interface 0: hard above / soft below")
    assert labels[1].startswith("interface 1: soft above / hard below")
    depth0 = float(sim.depth)
    for strip in row["LineStrips3D:strips"]:
        for x, y, z in np.array(strip, dtype=np.float64)[::12]:
            depth = depth0 - z  # the bit view's z is up: initial bit depth minus depth
            above = rock_at(x, y, depth - 1e-3, formation.normals, formation.offsets,
                            formation.layer_rock)
            below = rock_at(x, y, depth + 1e-3, formation.normals, formation.offsets,
                            formation.layer_rock)
            assert above != below  # a rock boundary of the physics' own formation


def test_chunks_written_out_of_time_order_read_back_sorted(tmp_path: Path,
                                                           case2: tuple[Any, Any]) -> None:
    sim, scenario = case2
    path = tmp_path / "order.rrd"
    stream, writer = _writer(path, sim, scenario)
    writer.scalars("timeseries/x", np.array([2.0, 3.0]), np.array([20.0, 30.0]))
    writer.scalars("timeseries/x", np.array([0.5, 1.0]), np.array([5.0, 10.0]))
    writer.events([(4.0, "INFO", "late"), (1.5, "WARN", "early")])  # one chunk
    writer.events([(0.7, "INFO", "earliest")])  # a later chunk, earlier in time
    stream.flush()
    del stream, writer
    back = read_recording(path)
    times, values = back.scalars["/timeseries/x"]
    np.testing.assert_allclose(times, [0.5, 1.0, 2.0, 3.0], atol=1e-9)
    np.testing.assert_allclose(values, [5.0, 10.0, 20.0, 30.0])
    events = back.text_logs["/events"]
    assert [e[1:] for e in events] == [("INFO", "earliest"), ("WARN", "early"),
                                       ("INFO", "late")]
    np.testing.assert_allclose([e[0] for e in events], [0.7, 1.5, 4.0], atol=1e-9)
    # in the file, each chunk's lines are in time order
    assert [r["TextLog:text"][0] for r in _rows(path)["/events"]] == [
        "early", "late", "earliest"]
    # the timeline is a duration of simulated time (not a wall-clock timestamp)
    from rerun.chunk import RrdReader
    reader = RrdReader(str(path))
    kinds = {str(chunk.to_record_batch().schema.field("sim_time").type)
             for chunk in reader.stream(store=reader.recordings()[0])
             if "sim_time" in chunk.to_record_batch().schema.names}
    assert kinds == {"duration[ns]"}


def test_the_orbit_view_is_in_mm_its_circle_the_clearance_and_its_bounds_around_it(
        tmp_path: Path, case2: tuple[Any, Any]) -> None:
    """docs/recording.md: ``orbit_mm/clearance`` is the gauge-clearance circle in mm, on
    the scale of the bit centre (``orbit_mm/bit``, mm), and the layout's orbit view frames
    that circle with a margin."""
    from rerun.chunk import RrdReader

    from drill_env.recording.recorder import EpisodeRecorder

    sim, scenario = case2
    clearance_mm = scenario.config.bit.gauge_clearance * 1e3
    recorder = EpisodeRecorder(tmp_path)
    recorder.begin(sim=sim, scenario="orbit", seed=None, info={
        "time": 0.0, "bit_lateral": np.array([0.5 * scenario.config.bit.gauge_clearance, 0.0])})
    path = recorder.finish(note="done")
    rows = _rows(path)
    (circle,) = rows["/orbit_mm/clearance"][0]["LineStrips2D:strips"]
    np.testing.assert_allclose(np.hypot(*np.array(circle).T), clearance_mm, rtol=F32)
    bit = [r["Points2D:positions"] for r in rows["/orbit_mm/bit"] if "Points2D:positions" in r]
    np.testing.assert_allclose(bit[0][0], [0.5 * clearance_mm, 0.0], rtol=F32)
    reader = RrdReader(str(path))
    bounds = [cell for chunk in reader.stream(store=reader.blueprints()[0])
              if "VisualBounds2D:range" in chunk.to_record_batch().schema.names
              for cell in chunk.to_record_batch().column("VisualBounds2D:range").to_pylist()]
    (cell,) = bounds  # one orbit view, one range
    (box,) = cell
    for low, high in (box["x_range"], box["y_range"]):
        assert low == -high and clearance_mm < high < 1.5 * clearance_mm


@pytest.mark.parametrize("name, factor", [("default", 500.0), ("stick_slip", 500.0),
                                          ("paper_case2", 200.0)])
def test_the_default_exaggeration_maps_the_largest_clearance_to_2_percent_of_the_string(
        name: str, factor: float) -> None:
    """docs/recording.md: a round number (``writer.nice``: 1, 2 or 5 x 10^k, at most the
    ratio) that maps the largest clearance to ~2 % of the string length: 500 for the
    ``default`` and ``stick_slip`` strings, 200 for the paper cases."""
    scenario = make_scenario(name)
    geometry = capture_geometry(Simulator(scenario.config), scenario.config)
    k = geometry.exaggeration()
    assert k == factor
    length = geometry.node_depth[-1] - geometry.node_depth[0]
    widest = k * np.max(geometry.node_clearance)
    assert 0.02 * length / 2.5 < widest <= 0.02 * length
    assert geometry.exaggeration(37.0) == 37.0  # one asked for is kept


@pytest.mark.parametrize("value, expected", [(5.0, 5.0), (2.0, 2.0), (1.0, 1.0), (50.0, 50.0),
                                             (200.0, 200.0), (0.5, 0.5), (9.99, 5.0),
                                             (4.99, 2.0), (1.99, 1.0), (499.0, 200.0),
                                             (0.3, 0.2)])
def test_nice_is_the_largest_1_2_or_5_times_a_power_of_ten_at_most_the_value(
        value: float, expected: float) -> None:
    """``writer.nice`` docstring: 1, 2 or 5 times a power of ten, at most ``value``: a
    value that is such a number is its own (5 is 5, not 2). (rel 1e-12: 10^-k is
    inexact in binary.)"""
    assert nice(value) == pytest.approx(expected, rel=1e-12)


def test_the_episode_fields_read_back_are_the_last_written(tmp_path: Path,
                                                           case2: tuple[Any, Any]) -> None:
    """``config/episode`` is logged at the start and again at the end, and the viewer
    shows the last (a static entity): so does ``read_recording``, also where the two
    are written in one batch."""
    sim, scenario = case2
    path = tmp_path / "episode.rrd"
    stream, writer = _writer(path, sim, scenario)
    writer.episode({"state": "running", "samples": 1})
    writer.episode({"state": "ended", "samples": 7})
    stream.flush()
    del stream, writer
    episode = read_recording(path).episode
    assert (episode["state"], episode["samples"]) == ("ended", 7)
