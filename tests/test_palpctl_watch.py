"""`palpctl watch` against the wire contract: a daemon's ROUTER and PUB sockets, served here on loopback.

The daemon side is played by this test so it can see what the watch does on the wire: each subscription
a SUB socket makes reaches an XPUB as a subscribe message. A subscription hears nothing published while it
connects (ZeroMQ's slow joiner), so a watch that re-subscribes whenever the stream is quiet for a moment
loses whatever is published in that window: beside a CPU hog, the e-stop's `fault` event was lost that way.
"""
import json
import signal
import subprocess
import sys
import time

import zmq

from palpd.bus.messages import FaultMsg, Status
from daemon_client import PORT_RANGE
from palpd.bus.replies import StatusReply


def test_watch_keeps_one_subscription_and_prints_a_fault_published_after_a_quiet_spell():
    context = zmq.Context()
    router, xpub = context.socket(zmq.ROUTER), context.socket(zmq.XPUB)
    xpub.setsockopt(zmq.XPUB_VERBOSE, 1)  # every subscribe reaches us, not only the first of a topic
    for socket in (router, xpub):
        socket.setsockopt(zmq.LINGER, 0)
    commands = f"tcp://127.0.0.1:{router.bind_to_random_port('tcp://127.0.0.1', *PORT_RANGE)}"
    events = f"tcp://127.0.0.1:{xpub.bind_to_random_port('tcp://127.0.0.1', *PORT_RANGE)}"
    watch = subprocess.Popen([sys.executable, "-m", "palpd.palpctl", "--endpoint", commands, "--events", events,
                              "watch"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    state, subscribes, status_seq, faulted = "ready", 0, 0, False
    try:
        poller = zmq.Poller()
        poller.register(router, zmq.POLLIN)
        poller.register(xpub, zmq.POLLIN)
        first_subscribe_s = None
        next_heartbeat_s = time.monotonic()
        while True:
            now = time.monotonic()
            if first_subscribe_s is not None and now > first_subscribe_s + 3.5:
                break
            assert now < next_heartbeat_s + 30, "the watch never subscribed"
            if now >= next_heartbeat_s:  # the daemon's heartbeat, once a second
                xpub.send_multipart([b"status", Status(seq=status_seq, t=now, state=state).model_dump_json().encode()])
                status_seq += 1
                next_heartbeat_s = now + 1.0
            if (first_subscribe_s is not None and not faulted and now > first_subscribe_s + 2.2
                    and next_heartbeat_s - now < 0.4):  # 0.6 s and more after the last event: a quiet spell
                state, faulted = "fault", True
                xpub.send_multipart([b"fault", FaultMsg(seq=0, t=now, code="estop",
                                                        message="emergency stop requested").model_dump_json().encode()])
            for socket, _ in poller.poll(20):
                if socket is xpub:
                    if xpub.recv()[:1] == b"\x01":
                        subscribes += 1
                        first_subscribe_s = first_subscribe_s or time.monotonic()
                else:
                    identity, body = router.recv_multipart()
                    request = json.loads(body)
                    reply = StatusReply(id=request["id"], seq=max(0, status_seq - 1), t=time.monotonic(), state=state)
                    router.send_multipart([identity, reply.model_dump_json().encode()])
        watch.send_signal(signal.SIGINT)
        out, err = watch.communicate(timeout=30)
    finally:
        watch.kill()
        context.destroy(linger=0)
    assert watch.returncode == 0, err
    lines = out.splitlines()
    assert lines[0] == "status: ready, 0 palpations", lines
    assert "fault: estop emergency stop requested" in lines, lines
    assert subscribes == 1, f"the watch subscribed {subscribes} times in 3.5 s"
