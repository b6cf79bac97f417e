"""A ROS 2 peer the project did not write: CycloneDDS's Python binding (one of ROS 2's own
middleware implementations) with the ROS 2 type names and topic mangling written out here
(`rt/<namespace>/<topic>`, `geometry_msgs::msg::dds_::PoseStamped_`), against
`host-sim ros2` in front of a board brought up (homed, enabled).

Checks, each waiting for its condition (the timeouts are failure detectors, never a
measure):
1. operating_state says ENABLED and homed;
2. measured_cp and measured_js arrive at the stated rate (100 Hz: the median interval
   over 300 intervals of the header stamps, which are the board's clock: load on the
   host does not change them), in pairs of one status (equal stamps), measured_cp in frame `base` with a
   unit quaternion inside the task box, measured_js with the six names of CONVENTIONS.md
   in order and SI values in the robot's ranges;
3. a servo_cp 5 mm from the measured pose brings measured_cp within TOLERANCE_MM of it;
4. an unreachable servo_cp (z = 250 mm) is refused on `refusal` with the board's
   reason in words (the workspace guard and its limit);
5. state_command disable makes operating_state DISABLED.

Environment: CYCLONEDDS_URI (the loopback configuration), RSPR_ROS_NAMESPACE (default
rspr), TOLERANCE_MM (default 0.05).
"""

import os
import statistics
import sys
import time
from dataclasses import dataclass, field

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, int32, sequence, uint32
from cyclonedds.internal import InvalidSample
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

NS = os.environ.get("RSPR_ROS_NAMESPACE", "rspr").strip("/")
TOLERANCE_MM = float(os.environ.get("TOLERANCE_MM", "0.05"))
RATE_HZ = 100.0
JOINTS = ["l1", "l2", "l3", "theta1", "theta2", "theta3"]


# --- The ROS 2 IDL, as rosidl generates it for DDS -------------------------------------
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: sequence[str] = field(default_factory=list)
    position: sequence[float64] = field(default_factory=list)
    velocity: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)


@dataclass
class OperatingState(IdlStruct, typename="crtk_msgs::msg::dds_::OperatingState_"):
    header: Header = field(default_factory=Header)
    state: str = ""
    is_homed: bool = False
    is_busy: bool = False


@dataclass
class StringStamped(IdlStruct, typename="crtk_msgs::msg::dds_::StringStamped_"):
    header: Header = field(default_factory=Header)
    string: str = ""


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str = ""


# --- ROS 2's default QoS: reliable, volatile, keep last 10 -----------------------------
QOS = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(10),
)

dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))


def reader(name, t):
    return DataReader(dp, Topic(dp, f"rt/{NS}/{name}", t), qos=QOS)


def writer(name, t):
    return DataWriter(dp, Topic(dp, f"rt/{NS}/{name}", t), qos=QOS)


measured_cp = DataReader(dp, Topic(dp, f"rt/{NS}/measured_cp", PoseStamped), qos=Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(1000),
))
measured_js = DataReader(dp, Topic(dp, f"rt/{NS}/measured_js", JointState), qos=Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(1000),
))
operating_state = reader("operating_state", OperatingState)
refusal = reader("refusal", String)
servo_cp = writer("servo_cp", PoseStamped)
state_command = writer("state_command", StringStamped)

failures = []
passed = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    (passed if ok else failures).append(what)
    return ok


def take(r):
    return [s for s in r.take(N=1000) if not isinstance(s, InvalidSample)]


def wait_for(what, timeout_s, poll):
    """Polls `poll()` (which returns a value or None) until it gives a value; the value,
    or None after timeout_s (a failure detector only)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        v = poll()
        if v is not None:
            return v
        time.sleep(0.002)
    print(f"     (no {what} within {timeout_s} s)", flush=True)
    return None


def stamp_s(h):
    return h.stamp.sec + h.stamp.nanosec * 1e-9


last_state = {}


def poll_state(pred):
    def p():
        for s in take(operating_state):
            last_state["s"] = s
            if pred(s):
                return s
        return None
    return p


# 1. the robot as the bridge brought it up
s = wait_for("operating_state ENABLED", 60, poll_state(lambda s: s.state == "ENABLED"))
check(s is not None and s.is_homed, f"operating_state ENABLED and homed: {s}")

# 2. measured_cp and measured_js at the stated rate, with their values
take(measured_cp)
take(measured_js)
cps, jss = [], []


def collect():
    cps.extend(take(measured_cp))
    jss.extend(take(measured_js))
    return True if len(cps) >= 301 and len(jss) >= 301 else None


wait_for("300 measured_cp and measured_js", 60, collect)
for name, msgs in (("measured_cp", cps), ("measured_js", jss)):
    stamps = [stamp_s(m.header) for m in msgs[:301]]
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    if not check(len(gaps) == 300, f"{name}: 301 messages received ({len(msgs)})"):
        continue
    rate = len(gaps) / (stamps[-1] - stamps[0])
    check(rate >= RATE_HZ * 0.99 and min(gaps) >= 0,
          f"{name}: {rate:.1f} Hz over 300 intervals of the stamps (>= 99), stamps never "
          f"going back; median interval {statistics.median(gaps) * 1e3:.2f} ms, longest "
          f"{max(gaps) * 1e3:.2f} ms")
cp = cps[-1]
check(cp.header.frame_id == "base", f"measured_cp frame_id {cp.header.frame_id!r} == 'base'")
q = cp.pose.orientation
norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w) ** 0.5
check(abs(norm - 1) < 1e-6, f"measured_cp orientation is a unit quaternion ({norm:.9f})")
p = cp.pose.position
# The bridge's robot holds the central pose after bring-up: inside the task box around
# [0, 0, hc = 160 mm] (CONVENTIONS.md, The reference robot).
check(abs(p.x) < 0.02 and abs(p.y) < 0.02 and 0.15 < p.z < 0.17,
      f"measured_cp inside the task box: ({p.x * 1e3:.3f}, {p.y * 1e3:.3f}, {p.z * 1e3:.3f}) mm")
js = jss[-1]
check(list(js.name) == JOINTS, f"measured_js names {list(js.name)} == {JOINTS}")
# SI: leg lengths in metres (144 .. 210 mm), link angles in radians (near 0 on the outer
# branch at the centre).
legs_ok = all(0.144 <= l <= 0.210 for l in js.position[:3])
links_ok = all(abs(a) < 0.5 for a in js.position[3:])
check(legs_ok and links_ok, f"measured_js in SI: {['%.5f' % v for v in js.position]}")
paired = {stamp_s(m.header) for m in cps} & {stamp_s(m.header) for m in jss}
check(len(paired) >= 290, f"measured_cp and measured_js come in pairs of one status ({len(paired)} of 300 stamps shared)")


def servo(x, y, z, q):
    servo_cp.write(PoseStamped(
        header=Header(stamp=Time(int(time.time()), 0), frame_id="base"),
        pose=Pose(position=Point(x, y, z), orientation=Quaternion(q.x, q.y, q.z, q.w)),
    ))


def latest_cp():
    got = take(measured_cp)
    if got:
        latest_cp.last = got[-1]
    return getattr(latest_cp, "last", None)


# 3. a servo_cp 5 mm away: the platform arrives within the tolerance
start = latest_cp() or cp
p, q = start.pose.position, start.pose.orientation
goal = (p.x + 0.003, p.y - 0.004, p.z)  # 5 mm
take(refusal)
servo(*goal, q)
t0 = time.monotonic()


def arrived():
    c = latest_cp()
    if c is None:
        return None
    d = ((c.pose.position.x - goal[0]) ** 2 + (c.pose.position.y - goal[1]) ** 2
         + (c.pose.position.z - goal[2]) ** 2) ** 0.5
    arrived.d = d
    return c if d * 1e3 <= TOLERANCE_MM else None


arrived.d = float("nan")
c = wait_for("arrival", 30, arrived)
refused = [r.data for r in take(refusal)]
check(c is not None,
      f"servo_cp 5 mm away: measured_cp within {TOLERANCE_MM} mm of it "
      f"({arrived.d * 1e3:.4f} mm, after {time.monotonic() - t0:.2f} s); refusals: {refused}")

# 4. an unreachable servo_cp: refused with its reason
servo(0.0, 0.0, 0.250, q)
r = wait_for("a refusal", 10, lambda: next(iter(take(refusal)), None))
text = r.data if r else ""
check(text.startswith("servo_cp refused: ") and "workspace" in text and "mm" in text,
      f"unreachable servo_cp refused with its reason: {text!r}")

# 5. state_command disable: DISABLED
state_command.write(StringStamped(header=Header(), string="disable"))
s = wait_for("operating_state DISABLED", 10, poll_state(lambda s: s.state == "DISABLED"))
check(s is not None, f"state_command disable: operating_state {s}")

# 6. a word CRTK does not have: refused with the words it takes
state_command.write(StringStamped(header=Header(), string="fly"))
r = wait_for("a refusal", 10, lambda: next(iter(take(refusal)), None))
check(r is not None and "unknown state_command" in r.data, f"unknown state_command refused: {r}")

print(f"{len(passed)} passed, {len(failures)} failed", flush=True)
sys.exit(1 if failures or not passed else 0)
