"""The 3-D tissue's force table (issue 49): built by finite elements, read per tick, cached per scene."""
import logging
import math

import numpy as np
import pytest

from drivers.sim.mechanics import table as T
from drivers.sim.scene import Scene

# a small layer with a stiff sphere whose top is 2 mm down: the production mesh on it builds in a few seconds
SMALL = {"name": "small-3d", "tissue": {"size_mm": [20.0, 20.0], "thickness_mm": 10.0, "modulus_kpa": 15.0},
         "inclusion": [{"shape": "sphere", "center_mm": [2.0, -2.0, 5.0], "radius_mm": 3.0, "modulus_kpa": 150.0}]}
# the table against the contact solved directly on the same mesh, averaged as the table is (1/4, 1/2, 1/4 over
# the neighbouring 2 mm node offsets, each way: a point load on a corner node and on a mid-side node of a P2
# element meet different compliances, and the raw solve ripples ±15 % node to node). Measured over 25 random
# points at δ 0.6-4.8 mm, before the onset below 2 mm was Hertz's: on grid points between tabulated depths (the
# power law) median 0.5 %, max 12 % (where the next ring of nodes enters the tip, δ 1-2 mm); between grid points
# median 4 %, max 27 %, most of it the direct solve's own ripple with the tip's place between nodes (against the
# raw solve: median 11 %, max 25 %). Now compared from 2 mm, where the mesh resolves the contact.
AT_NODES_MEDIAN, AT_NODES_MAX = 0.02, 0.15
BETWEEN_MEDIAN, BETWEEN_MAX = 0.06, 0.30
BINOMIAL = ((-1, 0.25), (0, 0.5), (1, 0.25))


def small_scene(**tissue) -> Scene:
    return Scene.model_validate({**SMALL, "tissue": {**SMALL["tissue"], **tissue}})


@pytest.fixture(scope="module")
def built():
    scene = small_scene()
    block = T.layer_compliance(scene)
    return scene, T.build_table(scene), T.surface_matrix(block, T._reach_mm(scene))


def test_the_table_reads_the_direct_contact_solve_between_its_grid_points(built):
    scene, table, (surface_xy, compliance) = built
    field = T.TableField(table)
    rng = np.random.default_rng(7)
    between, at_nodes = [], []
    for _ in range(25):
        # the tabulated range, inset, from the first depth whose contact the mesh resolves (below it, Hertz's onset)
        x, y, depth = rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(2.0, 4.8)
        for errors, (px, py) in ((between, (x, y)), (at_nodes, (2 * round(x / 2), 2 * round(y / 2)))):
            direct = sum(wx * wy * T.force_at(surface_xy, compliance, px + 2 * a, py + 2 * b, 2.5, [depth])[0]
                         for a, wx in BINOMIAL for b, wy in BINOMIAL)
            errors.append(abs(field.force_n(px, py, depth, 0.0) / direct - 1))
    assert np.median(at_nodes) < AT_NODES_MEDIAN and max(at_nodes) < AT_NODES_MAX, sorted(at_nodes)
    assert np.median(between) < BETWEEN_MEDIAN and max(between) < BETWEEN_MAX, sorted(between)
    # on a grid point at a tabulated depth it is the averaged solve itself
    i, j = 3, 4
    direct = sum(wx * wy * T.force_at(surface_xy, compliance, table.xs[i + a], table.ys[j + b], 2.5, [2.0])[0]
                 for a, wx in BINOMIAL for b, wy in BINOMIAL)
    assert field.force_n(table.xs[i], table.ys[j], 2.0) == pytest.approx(direct, rel=1e-9)


def test_below_the_depth_the_mesh_resolves_the_force_grows_as_hertz_from_its_onset(built):
    # A 2.5 mm tip's contact spans the 2 mm node spacing from δ = 1.6 mm (the table's 2 mm): before, it pressed
    # one node, a point load whose force grew linearly (0.5 and 1 mm) and then kinked upward as the next ring
    # entered. Over the sphere and beside it alike, F ∝ δ^1.5 up to 2 mm, and on from there as the mesh reads.
    scene, table, (surface_xy, compliance) = built
    field = T.TableField(table)
    for x, y in ((2.0, -2.0), (-6.0, 6.0)):
        at_2 = field.force_n(x, y, 2.0)
        for depth in (0.25, 0.5, 1.0, 1.5):
            assert field.force_n(x, y, depth) == pytest.approx(at_2 * (depth / 2.0) ** 1.5, rel=1e-9)
    one_node = T.force_at(surface_xy, compliance, 0.0, 0.0, 2.5, [0.5, 1.0])  # what the mesh alone gives
    assert one_node[1] / one_node[0] == pytest.approx(2.0, rel=1e-6)


def test_the_stiff_sphere_is_felt_over_it_and_not_far_from_it(built):
    _, table, _ = built
    field = T.TableField(table)
    over, beside = field.force_n(2.0, -2.0, 3.0), field.force_n(-7.0, 7.0, 3.0)
    assert over > 1.3 * beside
    assert [field.force_n(2.0, -2.0, d) for d in (0.0, -1.0)] == [0.0, 0.0]
    forces = [field.force_n(-6.0, 6.0, d) for d in (0.3, 0.5, 1.5, 3.0, 5.0, 6.0)]
    assert all(a < b for a, b in zip(forces, forces[1:])), forces  # deeper presses harder, past the table too


@pytest.mark.parametrize("centre", [(0.0, 0.0), (1.5, -2.0), (-3.0, 1.0)])
def test_a_sphere_is_felt_where_it_lies_whatever_way_the_mesh_splits_its_elements(centre):
    """Every hexahedron split along the same diagonal made the layer stiffer towards +x +y: a 3 mm sphere under
    (0, 0) was felt 0.55 mm off in x and in y, and paper-3d's rod was found 0.85 mm from where it lay (where
    the table's own bump was). Split mirrored in every other element, the bump's centre lies within 0.2 mm."""
    scene = Scene.model_validate({**SMALL, "inclusion": [{**SMALL["inclusion"][0], "center_mm": [*centre, 5.0]}]})
    table = T.build_table(scene, depths_mm=(1.0, 2.0))
    field = T.TableField(table)
    xs = np.arange(-9.0, 9.01, 0.25)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    k = np.array([[field.force_n(x, y, 1.0) for y in xs] for x in xs])
    excess = np.clip(k - np.median(k), 0.0, None)  # the bump over the layer's own reading
    felt = np.array([(gx * excess).sum(), (gy * excess).sum()]) / excess.sum()
    assert math.dist(felt, centre) < 0.2, felt


def test_a_homogeneous_layer_reads_the_bonded_layer_law_once_a_few_nodes_touch():
    from drivers.sim.mechanics.validation import bonded_layer_n

    scene = small_scene()
    scene = scene.model_copy(update={"inclusion": []})
    field = T.TableField(T.build_table(scene, depths_mm=(1.0, 2.0)))
    # The law is the paraboloid's: near enough the sphere at 1 mm, and too stiff as the contact's radius √(Rδ) nears
    # the tip's own (2.24 of 2.5 mm at 2 mm). Meshed twice as finely, this layer reads 0.994 and 0.867 of the law;
    # at the table's mesh, 0.98 and 0.90 (before its hexahedra were split mirrored, 1.04 and 0.95).
    for depth, low, high in ((1.0, 0.95, 1.05), (2.0, 0.82, 0.95)):
        ratio = field.force_n(0.0, 0.0, depth) / bonded_layer_n(15.0, 0.48, 2.5, depth, 10.0)
        assert low < ratio < high, (depth, ratio)


def test_a_homogeneous_layer_reads_alike_in_its_middle_its_sides_and_its_corners():
    # The palpable rectangle is part of a larger layer: meshed with a margin past its sides, it reads the same
    # everywhere. Sides on rollers alone (mirror planes) read a 20 mm layer's corners 15 % soft (the tip's
    # mirror images press too); with the margin, within 2 %. A thick layer: the thinner, the smaller the effect.
    scene = small_scene(thickness_mm=20.0).model_copy(update={"inclusion": []})
    field = T.TableField(T.build_table(scene, depths_mm=(2.0, 4.0)))
    for depth in (2.0, 4.0):
        middle = field.force_n(0.0, 0.0, depth)
        for x, y in ((9.9, 0.0), (-10.0, -10.0), (10.0, 10.0), (5.0, 3.0), (30.0, 0.0)):  # (30, 0): off it, its edge
            assert field.force_n(x, y, depth) == pytest.approx(middle, rel=0.03), (x, y, depth)


def test_the_table_is_cached_per_scene_and_a_corrupt_file_is_rebuilt(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path / "cache"))
    scene = small_scene(size_mm=[12.0, 12.0], thickness_mm=8.0)
    first = T.cached_table(scene, progress=False)
    [path] = (tmp_path / "cache").iterdir()
    assert path.suffix == ".npz" and not list((tmp_path / "cache").glob("*.tmp"))
    again = T.cached_table(scene, progress=False)
    assert again.build_s == first.build_s and np.array_equal(again.forces_n, first.forces_n)  # read, not rebuilt
    # another modulus is another table
    assert T.table_key(small_scene(size_mm=[12.0, 12.0], thickness_mm=8.0, modulus_kpa=20.0)) != first.key
    path.write_bytes(path.read_bytes()[:100])
    with caplog.at_level(logging.WARNING):
        rebuilt = T.cached_table(scene, progress=False)
    assert np.allclose(rebuilt.forces_n, first.forces_n)
    assert [r.message for r in caplog.records if "rebuilding" in r.message] and len(caplog.records) == 1
    assert T.ForceTable.load(path, first.key).forces_n.shape == first.forces_n.shape  # whole again


def test_the_cache_directory_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("PALPD_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert T.cache_dir() == tmp_path / "palpd"
    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path / "mine"))
    assert T.cache_dir() == tmp_path / "mine"
    monkeypatch.delenv("PALPD_CACHE_DIR")
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert T.cache_dir() == __import__("pathlib").Path.home() / ".cache" / "palpd"


def test_the_simulator_presses_a_3d_scene_by_its_table(tmp_path, monkeypatch):
    from drivers.sim.world import SimWorld

    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path))

    class Clock:
        def now(self):
            return 0.0

    scene = small_scene()
    world = SimWorld(scene, Clock())
    field = T.TableField(T.cached_table(scene, progress=False))
    assert world.felt_stiffness(2.0, -2.0) == pytest.approx(field.force_n(2.0, -2.0, 1.0))
    assert world.felt_stiffness(2.0, -2.0) > 1.3 * world.felt_stiffness(-7.0, 7.0)
    assert math.isfinite(world.felt_stiffness(50.0, 50.0))  # off the tissue: its edge


def test_a_cache_that_cannot_be_written_only_logs(tmp_path, monkeypatch, caplog):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("PALPD_CACHE_DIR", str(blocker / "cache"))  # under a file: no directory can be made
    with caplog.at_level(logging.WARNING):
        table = T.cached_table(small_scene(size_mm=[12.0, 12.0], thickness_mm=8.0), progress=False)
    assert table.forces_n.min() > 0
    [record] = caplog.records
    assert "not cached" in record.message and "\n" not in record.message


def test_the_tradeoff_bench_builds_a_3d_table_once_before_its_workers(tmp_path, monkeypatch):
    from palpd.commands.bench_tradeoff import _scenes

    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "small.toml").write_text('name = "small"\n[tissue]\nsize_mm = [12, 12]\nthickness_mm = 8\n'
                                         'modulus_kpa = 15\n')
    [scene] = _scenes([str(tmp_path / "small.toml")])
    assert scene.tissue.is_3d and len(list((tmp_path / "cache").glob("force-table-*.npz"))) == 1


def test_the_daemon_builds_the_table_before_its_servo_and_keeps_systemd_waiting(tmp_path, monkeypatch):
    import socket
    from types import SimpleNamespace

    from palpd.commands.serve import _prepare_3d_tissue

    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path / "cache"))
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(str(tmp_path / "notify"))
    listener.settimeout(5.0)
    monkeypatch.setenv("NOTIFY_SOCKET", str(tmp_path / "notify"))
    settings = SimpleNamespace(robot=SimpleNamespace(url="sim://"))
    _prepare_3d_tissue(settings, small_scene(size_mm=[12.0, 12.0], thickness_mm=8.0), logging.getLogger("t"))
    assert "EXTEND_TIMEOUT_USEC=" in listener.recv(4096).decode()
    assert len(list((tmp_path / "cache").glob("force-table-*.npz"))) == 1
    listener.close()


def test_a_3d_tissue_too_large_to_build_is_refused_in_one_line_at_once():
    from drivers.sim.scene import SceneError

    with pytest.raises(SceneError) as error:
        T.build_table(small_scene(size_mm=[150.0, 150.0], thickness_mm=30.0))
    message = str(error.value)
    assert "\n" not in message and "150 x 150 x 30 mm" in message and "size_mm or thickness_mm" in message


def test_palpd_scan_refuses_a_3d_tissue_too_large_to_build_with_exit_78(run_cli, tmp_path):
    from conftest import assert_one_line_error

    (tmp_path / "big.toml").write_text('name = "big"\n[tissue]\nsize_mm = [100, 100]\nthickness_mm = 20\n'
                                       'modulus_kpa = 15\n')
    result = run_cli("scan", "--scene", tmp_path / "big.toml", "--max-palpations", "2")
    assert result.returncode == 78
    assert_one_line_error(result, "100 x 100 x 20 mm", "unknowns")


def test_every_shipped_3d_scene_ships_its_table_and_reads_it_without_a_build(tmp_path, monkeypatch):
    from conftest import SCENES
    from drivers.sim.scene import load_scene

    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path))  # an empty cache: the table must come as shipped
    scenes = [scene for scene in map(load_scene, sorted(SCENES.glob("*.toml"))) if scene.tissue.is_3d]
    assert {"paper-3d", "sphere-3d"} <= {scene.name for scene in scenes}
    shipped = set()
    for scene in scenes:
        key = T.table_key(scene)
        path = T.SHIPPED_DIR / T.table_file_name(key)
        assert path.exists(), f"{scene.name}: no table of its key shipped: run `make tables`"
        table = T.cached_table(scene, progress=False)
        assert table.key == key and table.forces_n.shape == (31, 31, len(T.DEPTHS_MM))  # 2 mm nodes over 60 mm
        shipped.add(path.name)
    assert not list(tmp_path.iterdir())  # nothing was built into the cache
    assert sorted(p.name for p in T.SHIPPED_DIR.glob("*.npz")) == sorted(shipped)  # and no stale table ships


@pytest.mark.parametrize("speed_mm_s", [20.0, 40.0, 100.0])
def test_fast_presses_into_a_soft_3d_layer_stop_above_the_floor(speed_mm_s):
    # A Hertzian contact is felt late (its force grows as δ^1.5), so presses on a soft 3-D layer reach the
    # floor below the registered surface. Stopped there by the tip alone, the tip followed its setpoint (0.25
    # mm ahead at 20 mm/s) and its own speed through the floor: an `indentation` fault at 20 and 40 mm/s.
    from conftest import SCENES
    from drivers.sim.scene import load_scene
    from palpd.bench import open_simulated_bench
    from palpd.config import Settings
    from palpd.scan import plan, run_scan

    scene = load_scene(SCENES / "paper-3d.toml")
    settings = Settings().updated(scan={"strategy": "active"}, palpation={"speed_mm_s": speed_mm_s})
    report = run_scan(open_simulated_bench(settings, scene), settings, plan("active", scene.tissue.size_mm, 12, 0,
                                                                          settings))
    assert report["faults"] == [] and report["palpations"] == 12
    assert all(p["outcome"] == "fit" for p in report["probes"])
