#!/usr/bin/env python3
"""A pyigtl client against an OpenIGTLink robot server (this crate's fake_robot example, or
`host-sim igtl`).

    pyigtl_client.py HOST:PORT [--fake] [--tolerance-mm T]

Steps, each checked:
  1. read the robot's pose (TRANSFORM "Robot");
  2. send a TRANSFORM target 2 mm away (header version 1) and wait for the pose to get there;
  3. the same in protocol version 3 (header version 2, message id, metadata): the pose
     stream must switch to version 3;
  4. send a target 500 mm above the pose: expect a STATUS on "Target" with an error code
     (with --fake: code 8, "Unreachable"); against the board also one 2 mm above the
     workspace, one with a leg below its stroke and one tilted beyond the cone, each
     STATUS naming the guard, the value and the limit with its unit;
  5. send 4096 bytes of garbage on the same connection: the connection must survive (same
     socket, no reconnection, poses still arriving) and the server's counters (GET_STRING
     "Counters") must show the bad header;
  6. send the start pose back.
Prints "pyigtl: ..." figures; exits 1 on the first failure.

pyigtl 0.3.4 reads no STATUS and its POSITION is not the protocol's, so a STATUS class is
registered here (decoding the content per the protocol's STATUS page), and the GET_ queries
are header-only messages built on pyigtl's MessageBase.
"""

import argparse
import json
import random
import signal
import struct
import sys
import time

import numpy as np
import pyigtl
from pyigtl.messages import MessageBase, message_type_to_class_constructor


class StatusMessage(MessageBase):
    """STATUS: code uint16, sub code int64, error name char[20], message (NUL-terminated)."""

    def __init__(self, timestamp=None, device_name=None):
        MessageBase.__init__(self, timestamp=timestamp, device_name=device_name)
        self._message_type = "STATUS"
        self.code = 0
        self.subcode = 0
        self.error_name = ""
        self.status_string = ""
        self._valid_message = True

    def _unpack_content(self, content):
        self.code, self.subcode, name = struct.unpack("> H q 20s", content[:30])
        self.error_name = name.split(b"\0")[0].decode("utf8", "replace")
        self.status_string = content[30:].split(b"\0")[0].decode("utf8", "replace")


class QueryMessage(MessageBase):
    """A header-only query such as GET_STRING or GET_TRANS."""

    def __init__(self, message_type, device_name):
        MessageBase.__init__(self, device_name=device_name)
        self._message_type = message_type
        self._valid_message = True


message_type_to_class_constructor["STATUS"] = StatusMessage


def fail(what):
    print(f"pyigtl: FAIL: {what}", flush=True)
    sys.exit(1)


def wait_for(client, device, timeout, predicate=lambda m: True):
    """The next message from `device` for which `predicate` holds, or None."""
    end = time.time() + timeout
    while time.time() < end:
        m = client.wait_for_message(device, timeout=max(0.0, end - time.time()))
        if m is not None and predicate(m):
            return m
    return None


def pose_matrix(position_mm, rotation_vector_deg):
    """A 4x4 transform (mm) from a position and a rotation vector (deg, Rodrigues)."""
    r = np.radians(np.asarray(rotation_vector_deg, dtype=np.float64))
    angle = np.linalg.norm(r)
    m = np.eye(4)
    if angle > 0:
        k = r / angle
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        m[0:3, 0:3] = np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx
    m[0:3, 3] = position_mm
    return m


def refused(client, matrix, label, expected):
    """Sends a target the board must refuse; its STATUS names the guard, value and limit."""
    client.send_message(pyigtl.TransformMessage(matrix, device_name="Target"), wait=True)
    status = wait_for(client, "Target", 5.0,
                      lambda m: m.message_type == "STATUS" and m.code not in (0, 1))
    if status is None:
        fail(f"no STATUS for the target {label}")
    if expected not in status.status_string:
        fail(f"the refusal of the target {label} does not say {expected!r}: "
             f"{status.status_string!r}")
    print(f"pyigtl: target {label} answered: code {status.code} {status.error_name!r}: "
          f"{status.status_string}", flush=True)


def distance_mm(a, b):
    return float(np.linalg.norm(np.asarray(a)[0:3, 3] - np.asarray(b)[0:3, 3]))


def counters(client):
    client.send_message(QueryMessage("GET_STRING", "Counters"), wait=True)
    m = wait_for(client, "Counters", 5.0)
    if m is None:
        fail("no answer to GET_STRING Counters")
    return json.loads(m.string)


def move(client, matrix, tol_mm, version, label):
    """Sends a target and returns the seconds until the streamed pose is within tol_mm."""
    msg = pyigtl.TransformMessage(matrix, device_name="Target")
    if version == 2:
        msg.header_version = 2
        msg.message_id = 4242
        msg.metadata = {"Sender": "pyigtl_client"}
    t0 = time.time()
    client.send_message(msg, wait=True)
    m = wait_for(client, "Robot", 10.0, lambda m: distance_mm(m.matrix, matrix) <= tol_mm)
    if m is None:
        fail(f"{label}: the pose did not reach the target within 10 s")
    return time.time() - t0, m


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("address", help="HOST:PORT of the server")
    ap.add_argument("--fake", action="store_true", help="the server is the fake_robot example")
    ap.add_argument("--tolerance-mm", type=float, default=0.05)
    args = ap.parse_args()
    host, port = args.address.rsplit(":", 1)

    # pyigtl's send_message(wait=True) waits without limit: bound the whole run.
    signal.signal(signal.SIGALRM, lambda *_: fail("timed out after 120 s"))
    signal.alarm(120)
    client = pyigtl.OpenIGTLinkClient(host=host, port=int(port))
    end = time.time() + 5.0
    while not client.is_connected():
        if time.time() > end:
            fail(f"cannot connect to {args.address} within 5 s")
        time.sleep(0.01)
    # Ask for the pose stream (a server that pushes it on connection answers RTS_TRANS).
    client.send_message(QueryMessage("STT_TRANS", "Robot"), wait=True)
    client.send_message(QueryMessage("GET_TRANS", "Robot"), wait=True)
    start_msg = wait_for(client, "Robot", 5.0)
    if start_msg is None:
        fail("no TRANSFORM Robot within 5 s")
    start = np.array(start_msg.matrix, dtype=np.float64)
    print(f"pyigtl: start pose (mm) {np.round(start[0:3, 3], 3).tolist()}", flush=True)

    # 2. a version-1 target 2 mm along +x.
    goal = start.copy()
    goal[0, 3] += 2.0
    t_v1, _ = move(client, goal, args.tolerance_mm, 1, "version-1 target")

    # 3. a version-3 target 2 mm along +y: the stream must follow in version 3.
    goal3 = goal.copy()
    goal3[1, 3] += 2.0
    t_v3, reached = move(client, goal3, args.tolerance_mm, 2, "version-3 target")
    if reached.header_version != 2:
        fail(f"the pose came back in header version {reached.header_version}, the client spoke 2")

    # 4. a target the robot must refuse.
    far = goal3.copy()
    far[2, 3] += 500.0
    t0 = time.time()
    client.send_message(pyigtl.TransformMessage(far, device_name="Target"), wait=True)
    status = wait_for(client, "Target", 5.0, lambda m: m.message_type == "STATUS")
    t_refusal = time.time() - t0
    if status is None:
        fail("no STATUS on Target for the refused target")
    if status.code in (0, 1):
        fail(f"the refusal carries code {status.code}")
    if args.fake and (status.code != 8 or status.error_name != "Unreachable"):
        fail(f"fake robot: expected code 8 Unreachable, got {status.code} {status.error_name}")
    print(f"pyigtl: refused target answered: code {status.code} {status.error_name!r}: "
          f"{status.status_string}", flush=True)
    if not args.fake:
        # The board names the first guard the target breaks, with value and limit.
        if "workspace z" not in status.status_string or "> 175.0 mm" not in status.status_string:
            fail(f"the refusal does not name the workspace, value and limit: "
                 f"{status.status_string!r}")
        # 4b. just outside the box (z = 177 mm against 175): the board takes it and its path
        # check refuses it; that refusal is answered too.
        near = goal3.copy()
        near[2, 3] = 177.0
        client.send_message(pyigtl.TransformMessage(near, device_name="Target"), wait=True)
        later = wait_for(client, "Target", 5.0,
                         lambda m: m.message_type == "STATUS" and m.code not in (0, 1))
        if later is None:
            fail("no STATUS for the target 2 mm above the workspace")
        if "workspace z 177.0 mm > 175.0 mm" not in later.status_string:
            fail(f"the path check's refusal does not name the workspace: {later.status_string!r}")
        print(f"pyigtl: target 2 mm above the workspace answered: code {later.code} "
              f"{later.error_name!r}: {later.status_string}", flush=True)
        # 4c. inside the workspace box, a leg below its stroke (l1 132.5 mm, `host-sim ik
        # --pose 20,20,146,0,24,0`); 4d. the platform tilted beyond its 25 deg cone.
        refused(client, pose_matrix([20.0, 20.0, 146.0], [0.0, 24.0, 0.0]),
                "with leg 1 below its stroke", "stroke leg 1 132.5 mm < 144.0 mm")
        refused(client, pose_matrix([0.0, 0.0, 160.0], [26.0, 0.0, 0.0]),
                "tilted 26 deg", "platform tilt 26.0 deg > 25.0 deg")

    # 5. garbage on the same connection.
    before = counters(client)
    sock = client.socket
    rng = random.Random(1234)
    garbage = bytes(rng.randrange(256) for _ in range(4096))
    sock.sendall(garbage)
    time.sleep(0.3)
    after = counters(client)
    if client.socket is not sock or not client.is_connected():
        fail("pyigtl lost the connection after the garbage")
    if after["malformed"]["bad_header"] <= before["malformed"]["bad_header"]:
        fail(f"bad_header not counted: {before['malformed']} -> {after['malformed']}")
    if after["connections_closed"] != before["connections_closed"]:
        fail("the server closed a connection after the garbage")
    client.wait_for_message("Robot", timeout=0)  # drop the pose received before
    fresh = wait_for(client, "Robot", 5.0)
    if fresh is None:
        fail("no pose after the garbage")
    print(f"pyigtl: garbage: 4096 bytes, bad_header {before['malformed']['bad_header']} -> "
          f"{after['malformed']['bad_header']}, discarded_bytes {before['discarded_bytes']} -> "
          f"{after['discarded_bytes']}, connection kept", flush=True)

    # 6. back to the start.
    t_back, _ = move(client, start, args.tolerance_mm, 1, "return to start")

    final = counters(client)
    client.stop()
    print(f"pyigtl: 2 mm target reached in {t_v1 * 1000:.0f} ms (v1), {t_v3 * 1000:.0f} ms (v3), "
          f"{t_back * 1000:.0f} ms back; refusal STATUS after {t_refusal * 1000:.0f} ms "
          f"(pyigtl polls every 10 ms)", flush=True)
    print(f"pyigtl: server counters: received {final['received']}, sent {final['sent']}, "
          f"malformed {final['malformed']}, targets accepted {final['targets_accepted']}, "
          f"refused {final['targets_refused']}", flush=True)
    print("pyigtl: OK", flush=True)


if __name__ == "__main__":
    main()
