"""The learner as its own process: SUB `palpation` and `stiffness` from the daemon's bus, PUB `estimate` (with the
next probe).

It learns what the daemon's own learner does: each `stiffness` as a reading, and each `palpation` that gave
none by its outcome (a censored one as its bound, a failed one where it was aimed, so it is not asked for again).
A `palpation` whose outcome is `fit` waits for its `stiffness` event, which follows it.

The estimate socket is an XPUB so a subscriber that joins late gets the latest
estimate at once instead of waiting for the next stiffness point.
"""
from __future__ import annotations

import signal
import time

import zmq
from pydantic import ValidationError

from drivers.errors import describe_validation_error
from palpd.bus.messages import Estimate, LumpMsg, Palpation, Stiffness
from palpd.learner.planner import make_learner

POLL_MS = 200
HEARD = {b"stiffness": Stiffness, b"palpation": Palpation}


class LearnerService:
    def __init__(self, settings, context: zmq.Context | None = None, security=None) -> None:
        """security (palpd.bus.security.Security): CURVE for both sockets, as the daemon's bus has it."""
        self.settings = settings
        self.learner = make_learner(settings, settings.tissue.size_mm, settings.scan.seed)
        self.context = context or zmq.Context.instance()
        self.sub = self.context.socket(zmq.SUB)
        self.sub.setsockopt(zmq.LINGER, 0)
        for topic in HEARD:
            self.sub.setsockopt(zmq.SUBSCRIBE, topic)
        self.pub = self.context.socket(zmq.XPUB)
        self.pub.setsockopt(zmq.LINGER, 0)
        if security is not None:
            security.secure_client(self.sub)
            security.secure(self.pub)
        self.sub.connect(settings.bus.events)
        self.pub.bind(settings.bus.learner_events)
        self.seq = 0
        self.latest = self._estimate()
        self.running = True

    def serve(self) -> None:
        poller = zmq.Poller()
        poller.register(self.sub, zmq.POLLIN)
        poller.register(self.pub, zmq.POLLIN)
        while self.running:
            for sock, _ in poller.poll(POLL_MS):
                if sock is self.pub:
                    self._on_subscription(self.pub.recv())
                else:
                    self._on_event(self.sub.recv_multipart())

    def close(self) -> None:
        self.sub.close()
        self.pub.close()

    def _on_subscription(self, frame: bytes) -> None:
        if frame[:1] == b"\x01":  # a new subscriber: give it the latest estimate now
            self._publish(self.latest)

    def _on_event(self, frames: list[bytes]) -> None:
        topic = frames[0].decode(errors="replace")
        try:
            msg = HEARD.get(frames[0], Stiffness).model_validate_json(frames[-1])
        except ValidationError as exc:
            print(f"palpd learner: {describe_validation_error(topic + ' message', exc)}", flush=True)
            return
        if isinstance(msg, Stiffness):
            self.learner.observe(msg.xy_mm, msg.stiffness_n_per_mm, msg.stiffness_sd_n_per_mm)
        elif not self._observe_unfitted(msg):
            return
        self.latest = self._estimate(msg.t)
        self._publish(self.latest)

    def _observe_unfitted(self, msg: Palpation) -> bool:
        """A palpation that gave no stiffness, observed where it was aimed with its outcome (and bound); False
        for one whose `stiffness` event follows (from a daemon older than `outcome`: one with no reason given)."""
        outcome = msg.outcome or ("rejected" if msg.rejected else "fit")
        if outcome == "fit":
            return False
        self.learner.observe(msg.target_xy_mm or msg.xy_mm, None, outcome=outcome,
                             bound_n_per_mm=msg.stiffness_bound_n_per_mm)
        return True

    def _estimate(self, t: float | None = None) -> Estimate:
        nxt = self.learner.next_probe()
        self.seq += 1
        return Estimate(seq=self.seq, t=time.time() if t is None else t, points=self.learner.points,
                        lumps=[LumpMsg(**lump.as_dict()) for lump in self.learner.lumps()],
                        next_probe_mm=nxt, done=nxt is None, ambiguous_area_mm2=self.learner.ambiguous_area_mm2(),
                        model=self.learner.model())

    def _publish(self, estimate: Estimate) -> None:
        self.pub.send_multipart([b"estimate", estimate.model_dump_json().encode()])


def run_service(settings, security=None) -> int:
    service = LearnerService(settings, security=security)

    def stop(*_):
        service.running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print(f"palpd learner: stiffness from {settings.bus.events}, estimates on {settings.bus.learner_events}",
          flush=True)
    try:
        service.serve()
    finally:
        service.close()
    return 0
