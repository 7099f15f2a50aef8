"""palpd's MCAP writer checked by the official `mcap` reader: closed files, files cut by a crash, raw samples."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcap_official import read_closed, read_streaming
from palpd.bus.messages import EVENT_MODELS, SAMPLES_CHANNEL, RawSample, recording_schemas
from palpd.daemon.mcap import McapWriter, read_messages, seal


def status(seq: int) -> dict:
    return EVENT_MODELS["status"](seq=seq, t=0.5 * seq, state="scanning", palpations=seq).model_dump(mode="json")


def samples(count: int, t0_s: float = 10.0) -> list[dict]:
    return [{"t": t0_s + i / 1000, "tip_mm": (1.0, 2.0, -0.001 * i), "force_n": (0.0, 0.01, 0.002 * i),
             "normal_force_n": 0.002 * i, "status": 0} for i in range(count)]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A closed recording: two events, a batch of 1 kHz samples, one more event."""
    path = tmp_path_factory.mktemp("rec") / "recording-1.mcap"
    writer = McapWriter(path, recording_schemas())
    writer.write("status", status(0))
    writer.write("status", status(1))
    writer.record_samples(samples(250))
    writer.write("status", status(2))
    writer.close()
    return path


def test_the_official_reader_opens_a_closed_recording_with_every_schema_and_message(recorded):
    read = read_closed(recorded)
    assert read["header"].library == "palpd"
    assert read["schemas"]["status"] == EVENT_MODELS["status"].model_json_schema()
    assert read["schemas"][SAMPLES_CHANNEL] == RawSample.model_json_schema()
    topics = [topic for topic, _, _ in read["messages"]]
    assert topics == ["status"] * 2 + [SAMPLES_CHANNEL] * 250 + ["status"]
    assert [(t, p) for t, p, _ in read["messages"]] == read_messages(recorded)
    for topic, payload, _ in read["messages"]:
        (RawSample if topic == SAMPLES_CHANNEL else EVENT_MODELS[topic]).model_validate(payload)


def test_a_batch_of_samples_keeps_its_1khz_spacing_in_log_time(recorded):
    log_ns = [ns for topic, _, ns in read_closed(recorded)["messages"] if topic == SAMPLES_CHANNEL]
    gaps_s = [(b - a) / 1e9 for a, b in zip(log_ns, log_ns[1:])]
    assert all(math.isclose(gap, 1e-3, abs_tol=2e-6) for gap in gaps_s)


def test_a_malformed_sample_batch_is_refused_before_anything_is_written(tmp_path):
    writer = McapWriter(tmp_path / "r.mcap", recording_schemas())
    bad = samples(3)
    bad[2] = {**bad[2], "tip_mm": (1.0, 2.0)}
    with pytest.raises(ValueError, match="tip_mm"):
        writer.record_samples(bad)
    writer.close()
    assert read_messages(tmp_path / "r.mcap") == []


@settings(max_examples=40, deadline=None)
@given(cut=st.floats(min_value=0.0, max_value=1.0))
def test_a_file_cut_anywhere_reads_up_to_its_last_complete_message_and_seals(recorded, tmp_path_factory, cut):
    data = recorded.read_bytes()
    path = tmp_path_factory.mktemp("cut") / "recording-1.mcap"
    path.write_bytes(data[:int(cut * (len(data) - 30))])  # never the ending: a crash left it open
    ours = read_messages(path) if path.read_bytes()[:8] == data[:8] else []
    official, error = read_streaming(path)
    assert official == ours and error is not None  # the same prefix; the official reader then hits the torn tail
    if seal(path):
        assert [(t, p) for t, p, _ in read_closed(path)["messages"]] == ours
        assert not seal(path)  # sealed once is closed


def test_sealing_leaves_a_closed_file_alone(recorded):
    before = recorded.read_bytes()
    assert not seal(recorded) and recorded.read_bytes() == before
