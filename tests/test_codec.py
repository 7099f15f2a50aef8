"""The bridge codec: round trips, resynchronisation after garbage, corrupted frames rejected."""
from hypothesis import given, settings, strategies as st

from drivers.phantom import codec

seqs = st.integers(0, 0xFFFF)
currents = st.tuples(*[st.integers(-codec.MAX_CURRENT_MA, codec.MAX_CURRENT_MA)] * 3)
commands = st.builds(codec.Command, st.booleans(), st.booleans(), st.integers(0, 0xFFFF), currents,
                     st.integers(0, 0xFFFF), st.integers(0, 0xFFFF), currents)  # ... hold after, ramp, hold currents
states = st.builds(codec.State, st.tuples(*[st.integers(-2**31, 2**31 - 1)] * 3), st.integers(0, 255),
                   st.integers(0, 2**32 - 1), seqs, st.integers(0, 0xFFFF))
frames = st.one_of(
    st.builds(lambda s, c: (codec.encode_command(s, c), (codec.COMMAND, s, c)), seqs, commands),
    st.builds(lambda s, c: (codec.encode_state(s, c), (codec.STATE, s, c)), seqs, states),
    st.builds(lambda s: (codec.encode_frame(codec.READ, s), (codec.READ, s, None)), seqs),
)


def decoded(frame: codec.Frame):
    if frame.kind == codec.COMMAND:
        return frame.kind, frame.seq, codec.decode_command(frame.payload)
    if frame.kind == codec.STATE:
        return frame.kind, frame.seq, codec.decode_state(frame.payload)
    return frame.kind, frame.seq, None


def test_crc_is_ccitt_false():
    assert codec.crc16(b"123456789") == 0x29B1  # the standard check value


@given(st.lists(frames, max_size=8), st.integers(1, 40))
def test_frames_round_trip_whatever_the_chunking(items, chunk):
    stream = b"".join(raw for raw, _ in items)
    decoder = codec.FrameDecoder()
    out = []
    for i in range(0, len(stream), chunk):
        out += decoder.feed(stream[i:i + chunk])
    assert [decoded(f) for f in out] == [expected for _, expected in items]
    assert decoder.rejected_frames == 0 and decoder.discarded_bytes == 0


@given(st.lists(st.tuples(st.binary(max_size=40), frames), min_size=1, max_size=6))
@settings(max_examples=300)
def test_decoder_resynchronises_after_garbage(items):
    stream = b"".join(garbage + raw for garbage, (raw, _) in items)
    out = [decoded(f) for f in codec.FrameDecoder().feed(stream)]
    expected = [e for _, (_, e) in items]
    # Garbage may by chance contain a valid frame (CRC collision odds 1/65536): every real one must be there.
    assert all(e in out for e in expected)
    assert len(out) <= len(expected) + sum(len(g) for g, _ in items) // codec.OVERHEAD_BYTES


@given(st.lists(frames, min_size=3, max_size=6), st.data())
@settings(max_examples=300)
def test_a_corrupted_frame_is_rejected_and_its_neighbours_survive(items, data):
    victim = data.draw(st.integers(0, len(items) - 1))
    raw = bytearray(items[victim][0])
    position = data.draw(st.integers(2, len(raw) - 1))  # anything after the sync word
    raw[position] ^= 1 << data.draw(st.integers(0, 7))
    chunks = [bytes(raw) if i == victim else r for i, (r, _) in enumerate(items)]
    decoder = codec.FrameDecoder()
    out = [decoded(f) for f in decoder.feed(b"".join(chunks))]
    assert out == [e for i, (_, e) in enumerate(items) if i != victim]
    assert decoder.rejected_frames >= 1


@given(st.lists(st.tuples(st.binary(max_size=12), frames), max_size=6), st.binary(max_size=12))
@settings(max_examples=300)
def test_whole_chunks_decode_exactly_as_byte_by_byte(items, tail):
    """The in-place fast path for whole chunks and the buffered path agree on frames and on every counter."""
    stream = b"".join(garbage + raw for garbage, (raw, _) in items) + tail
    whole, trickled = codec.FrameDecoder(), codec.FrameDecoder()
    at_once = whole.feed(stream)
    one_by_one = [frame for i in range(len(stream)) for frame in trickled.feed(stream[i:i + 1])]
    assert at_once == one_by_one
    assert (whole.rejected_frames, whole.discarded_bytes) == (trickled.rejected_frames, trickled.discarded_bytes)


def test_a_truncated_frame_waits_for_the_rest():
    raw = codec.encode_command(7, codec.Command(True, False, 250, (100, -200, 300)))
    decoder = codec.FrameDecoder()
    assert decoder.feed(raw[:5]) == [] and decoder.feed(raw[5:-1]) == []
    (frame,) = decoder.feed(raw[-1:])
    assert codec.decode_command(frame.payload).currents_ma == (100, -200, 300)


def test_out_of_range_currents_are_clamped_not_wrapped():
    raw = codec.encode_command(1, codec.Command(True, False, 0, (40000, -40000, 0)))
    (frame,) = codec.FrameDecoder().feed(raw)
    assert codec.decode_command(frame.payload).currents_ma == (32767, -32767, 0)


@given(states)
def test_the_hosts_one_frame_fast_path_agrees_with_the_decoder(state):
    raw = codec.encode_state(9, state)
    assert codec.parse_state_frame(raw) == (9, state)
    (frame,) = codec.FrameDecoder().feed(raw)
    assert codec.decode_state(frame.payload) == state
    damaged = bytearray(raw)
    damaged[10] ^= 0x01
    assert codec.parse_state_frame(bytes(damaged)) is None and codec.parse_state_frame(raw + b"\x00") is None
