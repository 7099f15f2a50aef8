"""Issue 50's rough edges a newcomer met in the first hour, each pinned by a test that failed before the fix."""
import json
import os
import urllib.error
import urllib.request

import psutil
import pytest

from conftest import SCENES
from daemon_client import PORT_RANGE
from palpd import palpctl
from palpd.bus.messages import ScanStartArgs
from palpd.bus.replies import ScanStartReply
from palpd.commands import scan as scan_command
from palpd.config import Settings
from palpd.strategies import raster_note


def test_the_learner_is_the_default_strategy_of_settings_the_bus_and_palpctl(monkeypatch):
    assert Settings().scan.strategy == "active" and ScanStartArgs().strategy == "active"
    asked = {}

    class Recorder:
        def scan(self, strategy, **options):
            asked["strategy"] = strategy
            return ScanStartArgs()  # any model: palpctl prints it

    palpctl.run(Recorder(), palpctl.build_parser().parse_args(["scan", "start"]))
    assert asked["strategy"] == "active"


def test_a_raster_says_the_grid_it_lays_when_the_budget_is_not_square(capsys):
    assert raster_note(3) == "raster: 1 x 1 = 1 point (the largest square grid within 3)"
    assert raster_note(10) == "raster: 3 x 3 = 9 points (the largest square grid within 10)"
    assert raster_note(81) is None
    scan_command._note_raster(Settings().updated(scan={"strategy": "raster"}), 3)
    assert "1 x 1 = 1 point" in capsys.readouterr().err
    scan_command._note_raster(Settings(), 3)  # the learner spends its budget as it sees fit: nothing to say
    assert capsys.readouterr().err == ""

    class Daemon:
        def scan(self, strategy, **options):
            return ScanStartReply(id="1", session="s", expected_total=1, already_done=0)

    args = palpctl.build_parser().parse_args(["scan", "start", "--strategy", "raster", "--max-palpations", "3"])
    assert palpctl.run(Daemon(), args) == 0
    assert capsys.readouterr().err == "palpctl: raster: 1 x 1 = 1 point (the largest square grid within 3)\n"


def test_a_local_dask_cluster_serves_no_dashboard_and_binds_loopback_only():
    pytest.importorskip("distributed")
    from palpd.tradeoff.schedulers import local_cluster

    cluster = local_cluster(1, processes=False)
    try:
        listening = [c.laddr for c in psutil.Process(os.getpid()).net_connections("tcp") if c.status == "LISTEN"]
        assert listening and all(address.ip == "127.0.0.1" for address in listening), listening
        http_port = cluster.scheduler.http_server._sockets  # tornado's: {fd: socket}
        (port,) = {s.getsockname()[1] for s in http_port.values()}
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(f"http://127.0.0.1:{port}/status", timeout=5)
    finally:
        cluster.close()


def test_palpd_scenes_says_measured_map_and_counts_only_lumps_stiffer_than_the_tissue(capsys):
    from palpd.cli import main

    assert main(["scenes"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert "measured map," in lines["elongated-lump"] and "lump(s)" not in lines["elongated-lump"].split(",")[0]
    assert " 0 lump(s) and 1 softer spot(s)," in lines["soft-cyst"]  # a cyst is tissue to palpate, not a lump
    assert " 2 lump(s)," in lines["two-lumps"]


def test_building_the_package_gives_no_setuptools_warning_about_the_shipped_data_folders(tmp_path):
    """`make run` / `pip install .` printed ~150 lines: 'palpd.share.scenes' (and calibration, scenes.maps)
    absent from the packages configuration. build_py is the step that warns; in a copy, the tree stays clean."""
    import shutil
    import subprocess
    import sys

    from conftest import ROOT

    for name in ("setup.py", "pyproject.toml", "README.md", "palpd", "drivers", "config", "systemd"):
        copy = shutil.copytree if (ROOT / name).is_dir() else shutil.copy
        copy(ROOT / name, tmp_path / name, **({"ignore": shutil.ignore_patterns("__pycache__")}
                                               if (ROOT / name).is_dir() else {}))
    built = subprocess.run([sys.executable, "setup.py", "-q", "build_py", "--build-lib", "lib"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=60)
    assert built.returncode == 0, built.stderr
    assert "palpd.share" not in built.stderr, built.stderr
    assert (tmp_path / "lib/palpd/share/scenes/maps/half-stiff.csv").exists()


def test_a_missing_directory_is_one_line_naming_it_for_scan_report_and_palpctl_plot(tmp_path, capsys):
    """`palpd scan --report /no/such/dir/r.json` made the directory (as root, root's), `palpctl plot` refused."""
    from palpd.cli import main

    missing = tmp_path / "no" / "such"
    assert main(["scan", "--scene", "paper", "--quiet", "--report", str(missing / "r.json")]) != 0
    assert palpctl.main(["--endpoint", "tcp://127.0.0.1:9", "--timeout", "0.2", "plot", str(missing / "m.png")]) == 1
    said = capsys.readouterr().err.strip().splitlines()
    assert said == [f"palpd: {missing / 'r.json'}: cannot write: there is no directory {missing}",
                    f"palpctl: {missing / 'm.png'}: cannot write: there is no directory {missing}"]
    assert not (tmp_path / "no").exists()


def test_watch_with_no_events_on_its_endpoint_says_so_in_one_line_within_its_timeout():
    """The daemon answers commands, but --events names a port where nothing publishes: watch printed nothing
    and waited for ever, whatever --timeout said."""
    import subprocess
    import sys
    import threading
    import time

    import zmq

    from palpd.bus.replies import StatusReply

    context = zmq.Context()
    router = context.socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    commands = f"tcp://127.0.0.1:{router.bind_to_random_port('tcp://127.0.0.1', *PORT_RANGE)}"
    silent = context.socket(zmq.PUB)  # bound, so the SUB connects, and never publishes
    silent.setsockopt(zmq.LINGER, 0)
    events = f"tcp://127.0.0.1:{silent.bind_to_random_port('tcp://127.0.0.1', *PORT_RANGE)}"

    done = threading.Event()

    def answer_status() -> None:
        while not done.is_set():
            if not router.poll(50):
                continue
            peer, body = router.recv_multipart()
            request = json.loads(body)
            reply = StatusReply(id=request["id"], seq=0, t=0.0, state="ready", palpations=0).model_dump_json()
            router.send_multipart([peer, reply.encode()])

    answering = threading.Thread(target=answer_status)
    answering.start()
    started = time.monotonic()
    try:
        watch = subprocess.run([sys.executable, "-m", "palpd.palpctl", "--endpoint", commands, "--events", events,
                                "--timeout", "0.5", "watch"], capture_output=True, text=True, timeout=10)
    finally:
        done.set()
        answering.join()
        context.destroy(linger=0)
    assert watch.returncode == 1 and time.monotonic() - started < 5.0
    assert watch.stdout == "" and watch.stderr == f"palpctl: nothing answered on {events} within 0.5 s " \
                                                  "(is --events the daemon's event endpoint?)\n"


def test_probe_help_gives_units_and_frame_and_scan_help_names_the_default(capsys):
    with pytest.raises(SystemExit):
        palpctl.build_parser().parse_args(["probe", "--help"])
    said = " ".join(capsys.readouterr().out.split())
    assert "mm in the tissue frame: origin at the centre of the palpable rectangle" in said
    assert "stiffness in N/mm" in said
    from palpd.cli import main

    with pytest.raises(SystemExit):
        main(["scan", "--help"])
    assert "active (default)" in " ".join(capsys.readouterr().out.split())
