"""Recordings by the official `mcap` Writer: chunked, compressed, indexed; a file cut by a crash is sealed."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcap_official import read_closed, read_streaming
from palpd.bus.messages import EVENT_MODELS, SAMPLES_CHANNEL, RawSample, recording_schemas
from palpd.daemon.mcap import McapWriter, is_closed, read_messages, seal


def status(seq: int) -> dict:
    return EVENT_MODELS["status"](seq=seq, t=0.5 * seq, state="scanning", palpations=seq).model_dump(mode="json")


def samples(count: int, t0_s: float = 10.0) -> list[dict]:
    return [{"t": t0_s + i / 1000, "tip_mm": (1.0, 2.0, -0.001 * i), "force_n": (0.0, 0.01, 0.002 * i),
             "normal_force_n": 0.002 * i, "status": 0} for i in range(count)]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A closed recording of three chunks (the daemon finishes one each second): events and 1 kHz samples."""
    path = tmp_path_factory.mktemp("rec") / "recording-1.mcap"
    writer = McapWriter(path, recording_schemas())
    writer.write("status", status(0))
    writer.write("status", status(1))
    writer.flush()
    writer.record_samples(samples(250))
    writer.flush()
    writer.write("status", status(2))
    writer.close()
    return path


def test_the_official_reader_opens_a_closed_recording_with_every_schema_and_message(recorded):
    read = read_closed(recorded)
    assert read["header"].library == "palpd"
    assert read["schemas"] == recording_schemas()  # every channel, messages or not, with its published schema
    topics = [topic for topic, _, _ in read["messages"]]
    assert topics == ["status"] * 2 + [SAMPLES_CHANNEL] * 250 + ["status"]
    assert [(t, p) for t, p, _ in read["messages"]] == read_messages(recorded)
    for topic, payload, _ in read["messages"]:
        (RawSample if topic == SAMPLES_CHANNEL else EVENT_MODELS[topic]).model_validate(payload)


def test_a_recording_is_chunked_compressed_and_indexed(recorded):
    summary = read_closed(recorded)["summary"]
    assert len(summary.chunk_indexes) == 3 and summary.statistics.message_count == 253
    assert all(c.compression == "zstd" and c.message_index_offsets for c in summary.chunk_indexes)
    samples_chunk = max(summary.chunk_indexes, key=lambda c: c.uncompressed_size)
    assert samples_chunk.compressed_size < samples_chunk.uncompressed_size / 4


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


@settings(max_examples=25, deadline=None)
@given(cut=st.floats(min_value=0.0, max_value=1.0))
def test_a_file_cut_anywhere_keeps_every_finished_chunk_and_seals_to_an_indexed_file(recorded, tmp_path_factory,
                                                                                     cut):
    data = recorded.read_bytes()
    whole = read_messages(recorded)
    summary = read_closed(recorded)["summary"]
    path = tmp_path_factory.mktemp("cut") / "recording-1.mcap"
    end = int(cut * summary.chunk_indexes[-1].chunk_start_offset + 200)  # a crash never wrote the summary
    path.write_bytes(data[:end])
    kept = read_messages(path)
    finished = [c for c in summary.chunk_indexes if c.chunk_start_offset + c.chunk_length <= end]
    assert kept == whole[:len(kept)] and len(kept) >= sum(_messages_in(summary, c) for c in finished)
    official, error = read_streaming(path)
    assert official == kept and error is not None  # the official streaming reader agrees, then hits the torn tail
    assert seal(path) and is_closed(path)
    sealed = read_closed(path)
    assert [(t, p) for t, p, _ in sealed["messages"]] == kept
    assert len(sealed["summary"].chunk_indexes) == (1 if kept else 0)
    assert not seal(path)  # sealed once is closed


def _messages_in(summary, chunk) -> int:
    """Messages of the fixture's chunks, in order: two statuses, 250 samples, one status."""
    return (2, 250, 1)[summary.chunk_indexes.index(chunk)]


def test_sealing_leaves_a_closed_file_alone(recorded):
    before = recorded.read_bytes()
    assert not seal(recorded) and recorded.read_bytes() == before
