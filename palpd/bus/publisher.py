"""Event publisher: PUB with a high-water mark, so a slow subscriber loses events instead of stalling palpd."""
from __future__ import annotations

import zmq

from palpd.bus.messages import EVENT_MODELS, Event


def bind_or_close(socket: zmq.Socket, endpoint: str) -> None:
    """Bind, or close the socket before the error propagates: a socket left open blocks the
    context's termination, and a daemon that cannot bind must exit, not hang."""
    try:
        socket.bind(endpoint)
    except zmq.ZMQError:
        socket.close(linger=0)
        raise


class EventPublisher:
    """Sends [topic, json] with a per-topic seq; validates every payload against its model."""

    def __init__(self, context: zmq.Context, endpoint: str, high_water_mark: int, security) -> None:
        self.socket = context.socket(zmq.PUB)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.SNDHWM, high_water_mark)
        security.secure(self.socket)
        bind_or_close(self.socket, endpoint)
        self._seq = {topic: 0 for topic in EVENT_MODELS}

    def publish(self, topic: str, t: float, **fields) -> Event:
        """Build, validate and send one event; returns it (the recorder and estimate.get keep it)."""
        event = EVENT_MODELS[topic](seq=self._seq[topic], t=t, **fields)
        self._seq[topic] += 1
        try:
            # PUB never blocks: at the high-water mark it drops for that subscriber.
            self.socket.send_multipart([topic.encode(), event.model_dump_json().encode()], zmq.NOBLOCK)
        except zmq.Again:
            pass
        return event

    def last_seq(self, topic: str) -> int:
        """The seq of the latest event published on a topic (0 before the first)."""
        return max(self._seq[topic] - 1, 0)

    def close(self) -> None:
        self.socket.close(linger=0)
