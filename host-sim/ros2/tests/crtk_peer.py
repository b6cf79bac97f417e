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
5. /joint_states carries every joint of the URDF (`host-sim describe --urdf`), named and
   ordered as its non-fixed joints, and its actuated joints equal measured_js of the same
   status (same stamp) to 1e-12 m and rad (the node's forward kinematics stops at a
   residual of 1e-15 m / 1e-14 rad, the angles compared modulo 2 pi); /tf of the same
   status has one transform per URDF joint, parent and child links as the URDF's;
6. state_command pause: operating_state PAUSED; while a servo_cp 2 mm away is streamed
   (one per measured_cp) and refused with the reason (paused), measured_cp stays within
   0.01 mm of where the robot stopped over 100 statuses; state_command resume with the
   stream still running: ENABLED, and the platform arrives within TOLERANCE_MM;
7. a servo_jp 3 mm away (the inverse kinematics of the pose by `host-sim ik`, the names
   in reverse order) brings measured_cp within TOLERANCE_MM of that pose;
8. bad servo_jp (five joints; an unknown name; legs of 10 mm with the links at 0, which
   no pose has: the spherical-joint centres are then 190.5 mm apart, the platform joints
   86.6 mm) are refused on `refusal` with what is wrong;
9. state_command disable makes operating_state DISABLED.

Environment: CYCLONEDDS_URI (the loopback configuration), RSPR_ROS_NAMESPACE (default
rspr), TOLERANCE_MM (default 0.05), RSPR_URDF (the URDF file), HOST_SIM (the binary, for
`ik`).
"""

import math
import os
import statistics
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
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


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped] = field(default_factory=list)


KEEP_1000 = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(1000),
)
# /joint_states and /tf are absolute topics (where robot_state_publisher and RViz look).
joint_states = DataReader(dp, Topic(dp, "rt/joint_states", JointState), qos=KEEP_1000)
tf = DataReader(dp, Topic(dp, "rt/tf", TFMessage), qos=KEEP_1000)
servo_jp = writer("servo_jp", JointState)
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

# 5. /joint_states: every URDF joint, the actuated ones equal measured_js
urdf = ET.parse(os.environ["RSPR_URDF"]).getroot()
urdf_joints = [j for j in urdf.findall("joint")]
moving = [j.get("name") for j in urdf_joints if j.get("type") != "fixed"]
urdf_edges = {(j.find("parent").get("link"), j.find("child").get("link")) for j in urdf_joints}
take(measured_js)
take(joint_states)
take(tf)
got = {"js": {}, "full": {}, "tf": {}}


def shared_stamp():
    for m in take(measured_js):
        got["js"][stamp_s(m.header)] = m
    for m in take(joint_states):
        got["full"][stamp_s(m.header)] = m
    for m in take(tf):
        if m.transforms:
            got["tf"][stamp_s(m.transforms[0].header)] = m
    both = sorted(set(got["js"]) & set(got["full"]) & set(got["tf"]))
    return both if len(both) >= 50 else None


stamps = wait_for("50 statuses with measured_js, /joint_states and /tf", 30, shared_stamp) or []
check(len(stamps) >= 50, f"/joint_states and /tf published with measured_js ({len(stamps)} statuses)")
names_ok = all(list(got["full"][t].name) == moving for t in stamps)
full0 = got["full"][stamps[0]] if stamps else JointState()
check(bool(stamps) and names_ok,
      f"/joint_states names are the URDF's {len(moving)} moving joints in order: {list(full0.name)}")


def angle_diff(a, b):
    return abs(math.remainder(a - b, 2 * math.pi))


worst = 0.0
for t in stamps:
    full = dict(zip(got["full"][t].name, got["full"][t].position))
    js = got["js"][t]
    for n, v in zip(js.name, js.position):
        d = abs(full.get(n, float("nan")) - v) if n.startswith("l") else angle_diff(full.get(n, float("nan")), v)
        worst = max(worst, d) if d == d else float("inf")
check(bool(stamps) and worst <= 1e-12,
      f"/joint_states actuated joints equal measured_js of the same status (worst {worst:.2e} m or rad <= 1e-12)")
passive = [n for n in moving if n not in JOINTS]
check(bool(stamps) and len(passive) == len(moving) - 6 and all(
    all(math.isfinite(v) for v in got["full"][t].position) for t in stamps),
      f"/joint_states has the {len(passive)} passive joints too, all finite")
tf_edges_ok = all({(x.header.frame_id, x.child_frame_id) for x in got["tf"][t].transforms} == urdf_edges
                  and len(got["tf"][t].transforms) == len(urdf_joints) for t in stamps)
check(bool(stamps) and tf_edges_ok,
      f"/tf: one transform per URDF joint ({len(urdf_joints)}), parent and child links as the URDF's")


def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def qrot(q, v):
    x, y, z, _ = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return (x, y, z)


def platform_by_tf(m):
    """The platform frame in base, composed along /tf's parent links."""
    by_child = {x.child_frame_id: x for x in m.transforms}
    t, q, frame = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), "platform"
    while frame != "base":
        x = by_child[frame].transform
        xq = (x.rotation.x, x.rotation.y, x.rotation.z, x.rotation.w)
        t = tuple(a + b for a, b in zip(qrot(xq, t), (x.translation.x, x.translation.y, x.translation.z)))
        q = qmul(xq, q)
        frame = by_child[frame].header.frame_id
    return t, q


cp_by_stamp = {stamp_s(m.header): m for m in cps}
for m in take(measured_cp):
    cp_by_stamp[stamp_s(m.header)] = m
worst_t = worst_r = 0.0
compared = 0
for t in stamps:
    if t not in cp_by_stamp:
        continue
    pt, pq = platform_by_tf(got["tf"][t])
    c = cp_by_stamp[t].pose
    worst_t = max(worst_t, math.dist(pt, (c.position.x, c.position.y, c.position.z)))
    dot = abs(sum(a * b for a, b in zip(pq, (c.orientation.x, c.orientation.y, c.orientation.z, c.orientation.w))))
    worst_r = max(worst_r, 2 * math.acos(min(1.0, dot)))
    compared += 1
# The bound: measured_cp is the board's single-precision forward kinematics of the same
# encoders (its iteration stops at 7.6e-7 m / 7.6e-6 rad of joint residual, each joint's
# gain onto the pose below 1 m/m and 0.1 m/rad near the centre, the pose rounded to f32:
# 1.5e-8 m at 0.16 m), /tf the double-precision one: they agree to a few 1e-6.
check(compared >= 10 and worst_t <= 1e-5 and worst_r <= 1e-4,
      f"/tf puts platform at measured_cp of the same status over {compared} statuses "
      f"(worst {worst_t:.2e} m <= 1e-5, {worst_r:.2e} rad <= 1e-4)")


def stream_until(goal, q, cond):
    """Sends servo_cp `goal` once per measured_cp received, until cond(cp) gives a value."""
    def poll():
        got_cp = take(measured_cp)
        if not got_cp:
            return None
        servo(*goal, q)
        for c in got_cp:
            v = cond(c)
            if v is not None:
                return v
        return None
    return poll


def dist_mm(c, goal):
    p = c.pose.position
    return math.dist((p.x, p.y, p.z), goal) * 1e3


# 6. pause: the robot holds while a servo_cp 2 mm away is streamed; resume: it arrives
state_command.write(StringStamped(header=Header(), string="pause"))
s = wait_for("operating_state PAUSED, not busy", 10,
             poll_state(lambda s: s.state == "PAUSED" and not s.is_busy))
check(s is not None, f"state_command pause: operating_state {s}")
take(measured_cp)
held = wait_for("a measured_cp", 10, lambda: next(iter(take(measured_cp)), None))
hp, hq = held.pose.position, held.pose.orientation
hold = (hp.x, hp.y, hp.z)
goal = (hp.x - 0.002, hp.y, hp.z)  # 2 mm
take(refusal)
watch = {"refusals": [], "after": 0, "worst": 0.0}


def held_while_refused(c):
    watch["refusals"] += [r.data for r in take(refusal)]
    watch["worst"] = max(watch["worst"], dist_mm(c, hold))
    if watch["refusals"]:
        watch["after"] += 1
    return True if watch["after"] >= 100 else None


wait_for("100 statuses after the first refusal", 30, stream_until(goal, hq, held_while_refused))
r0 = watch["refusals"][0] if watch["refusals"] else ""
check(r0.startswith("servo_cp refused: ") and "paused" in r0,
      f"servo_cp while paused refused with the reason: {r0!r} ({len(watch['refusals'])} refusals)")
check(watch["after"] >= 100 and watch["worst"] <= 0.01,
      f"paused: measured_cp within 0.01 mm of where it stopped over {watch['after']} statuses "
      f"while servo_cp 2 mm away streamed (worst {watch['worst']:.4f} mm)")
state_command.write(StringStamped(header=Header(), string="resume"))
arrival = {"d": float("nan"), "enabled": None}


def arrives(c):
    for st in take(operating_state):
        if st.state == "ENABLED":
            arrival["enabled"] = st
    arrival["d"] = dist_mm(c, goal)
    return c if arrival["d"] <= TOLERANCE_MM and arrival["enabled"] is not None else None


t0 = time.monotonic()
c = wait_for("arrival after resume", 30, stream_until(goal, hq, arrives))
check(c is not None,
      f"state_command resume: ENABLED, and the streamed servo_cp 2 mm away arrives within "
      f"{TOLERANCE_MM} mm ({arrival['d']:.4f} mm, after {time.monotonic() - t0:.2f} s)")


# 7. servo_jp 3 mm away
def rotvec_deg(q):
    s_ = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z)
    if s_ < 1e-15:
        return (0.0, 0.0, 0.0)
    angle = 2 * math.atan2(s_, q.w)
    return tuple(math.degrees(angle) * v / s_ for v in (q.x, q.y, q.z))


def ik(pose_m, q):
    """The actuated joints (m, rad) of a pose, by `host-sim ik` (branch 0)."""
    arg = ",".join(f"{v:.9f}" for v in [x * 1e3 for x in pose_m] + list(rotvec_deg(q)))
    out = subprocess.run([os.environ["HOST_SIM"], "ik", "--csv"], input=
                         "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n" + arg + "\n",
                         capture_output=True, text=True, check=True).stdout.splitlines()
    row = dict(zip(out[0].split(","), out[1].split(",")))
    return [float(row[f"{n}_mm"]) * 1e-3 for n in JOINTS[:3]] + \
           [math.radians(float(row[f"{n}_deg"])) for n in JOINTS[3:]]


take(measured_cp)
here_cp = wait_for("a measured_cp", 10, lambda: next(iter(take(measured_cp)), None))
hp, hq = here_cp.pose.position, here_cp.pose.orientation
goal = (hp.x + 0.002, hp.y + 0.002, hp.z + 0.001)  # 3 mm
qj = ik(goal, hq)
take(refusal)
servo_jp.write(JointState(header=Header(), name=JOINTS[::-1], position=qj[::-1]))
arrival = {"d": float("nan")}


def jp_arrived():
    for c in take(measured_cp):
        arrival["d"] = dist_mm(c, goal)
        if arrival["d"] <= TOLERANCE_MM:
            return c
    return None


t0 = time.monotonic()
c = wait_for("arrival of servo_jp", 30, jp_arrived)
refused = [r.data for r in take(refusal)]
check(c is not None,
      f"servo_jp 3 mm away ({', '.join('%.6f' % v for v in qj)}): measured_cp within "
      f"{TOLERANCE_MM} mm of its pose ({arrival['d']:.4f} mm, after "
      f"{time.monotonic() - t0:.2f} s); refusals: {refused}")

# 8. bad servo_jp: refused with what is wrong
for what, names, values, expect in (
        ("five joints", JOINTS[:5], qj[:5], "names 5 joints"),
        ("an unknown name", ["l4"] + JOINTS[1:], qj, 'name[0] is "l4"'),
        ("legs of 10 mm", JOINTS, [0.01, 0.01, 0.01, 0.0, 0.0, 0.0], "no forward kinematics")):
    servo_jp.write(JointState(header=Header(), name=names, position=values))
    r = wait_for("a refusal", 10, lambda: next(iter(take(refusal)), None))
    text = r.data if r else ""
    check(text.startswith("servo_jp refused: ") and expect in text,
          f"servo_jp with {what} refused with the reason: {text!r}")

# 9. state_command disable: DISABLED
state_command.write(StringStamped(header=Header(), string="disable"))
s = wait_for("operating_state DISABLED", 10, poll_state(lambda s: s.state == "DISABLED"))
check(s is not None, f"state_command disable: operating_state {s}")

# 10. a word CRTK does not have: refused with the words it takes
state_command.write(StringStamped(header=Header(), string="fly"))
r = wait_for("a refusal", 10, lambda: next(iter(take(refusal)), None))
check(r is not None and "unknown state_command" in r.data, f"unknown state_command refused: {r}")

print(f"{len(passed)} passed, {len(failures)} failed", flush=True)
sys.exit(1 if failures or not passed else 0)
