//! The steps of a teleoperation run and the checks of the CI scenario, each printed with
//! its figures.

use crate::error::TeleopError;
use crate::session::{Session, StatusRow};
use crate::start::{self, StartOptions};
use crate::tracking::{deviation, rms_max, Pass};
use kinematics_core::Pose;
use master_link::{
    cobs, encode, FaultCause, Header, MasterToBoard, NackReason, RobotState, StatusReport,
    StopStatus, Warnings, CRC32, CRC_LEN, MAX_FRAME_LEN, PROTOCOL_VERSION,
};
use nalgebra::Vector3;
use trajectory::Trajectory;

/// One check's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct Check {
    /// What was checked.
    pub name: String,
    /// Passed.
    pub ok: bool,
    /// The figures behind it.
    pub figures: String,
}

/// The checks so far, printed as they come.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Checks {
    /// In order.
    pub list: Vec<Check>,
}

impl Checks {
    /// Records and prints a check.
    pub fn check(&mut self, name: &str, ok: bool, figures: String) {
        println!(
            "check {name}: {}\n    {figures}",
            if ok { "ok" } else { "FAILED" }
        );
        self.list.push(Check {
            name: name.into(),
            ok,
            figures,
        });
    }

    /// Every check passed.
    pub fn all_ok(&self) -> bool {
        self.list.iter().all(|c| c.ok)
    }
}

/// The measured pose of a status.
pub fn measured_pose(s: &StatusReport) -> Option<Pose<f64>> {
    let v = |a: [f32; 3]| Vector3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2]));
    Pose::from_position_rotation_vector(v(s.position_m), v(s.rotation_vector_rad)).ok()
}

fn position(s: &StatusReport) -> Vector3<f64> {
    let [x, y, z] = s.position_m.map(f64::from);
    Vector3::new(x, y, z)
}

/// Largest distance of the statuses' positions from `from`, m.
fn max_displacement<'a>(rows: impl Iterator<Item = &'a StatusRow>, from: &Vector3<f64>) -> f64 {
    rows.map(|r| (position(&r.status) - from).norm())
        .fold(0.0, f64::max)
}

/// Waits (at most `timeout_s`) until the measured position has stayed within 1 µm over
/// five statuses (0.1 s at the board's 20 ms), then 0.2 s more.
fn settle(s: &mut Session, timeout_s: f64) -> Result<(), TeleopError> {
    let end = s.now_s() + timeout_s;
    loop {
        s.wait(0.05)?;
        let n = s.statuses.len();
        let still = s.statuses.get(n.saturating_sub(5)..).is_some_and(|last| {
            last.len() == 5
                && last
                    .iter()
                    .all(|r| (position(&r.status) - position(&last[4].status)).norm() < 1e-6)
        });
        if still || s.now_s() >= end {
            break;
        }
    }
    s.wait(0.2)
}

fn mm(m: f64) -> String {
    format!("{:.4} mm", m * 1e3)
}

/// Hello: the board answers with its versions.
pub fn hello(s: &mut Session, checks: &mut Checks, timeout_s: f64) -> Result<(), TeleopError> {
    s.phase("hello");
    let t0 = s.now_s();
    let (fw, proto) = s.hello(timeout_s)?;
    checks.check(
        "hello",
        proto == PROTOCOL_VERSION,
        format!(
            "firmware {}.{}.{}, protocol {proto} (master {PROTOCOL_VERSION}), answered after {:.2} s",
            fw.major,
            fw.minor,
            fw.patch,
            s.now_s() - t0
        ),
    );
    Ok(())
}

/// How long the way out waits for the answer to its `Disable`, s: well inside the
/// board's heartbeat timeout, so that a front end that ends is never taken for a lost
/// master.
pub const DISABLE_TIMEOUT_S: f64 = 0.2;

/// The board as found after the Hello (see [`crate::start`]): an unacknowledged reset
/// acknowledged only with `options.acknowledge_reset`, a latched fault cleared only with
/// `options.clear_fault`, a robot running under another master refused. Whether the robot
/// is homed already (then the run skips homing).
pub fn prepare(
    s: &mut Session,
    checks: &mut Checks,
    options: StartOptions,
) -> Result<bool, TeleopError> {
    s.phase("prepare");
    if let Some(reset) = s.reset.filter(|r| !r.acknowledged) {
        if !options.acknowledge_reset {
            return Err(TeleopError::ResetNotAcknowledged(reset.cause));
        }
        let nack = s.request(MasterToBoard::AcknowledgeReset, 1.0)?;
        checks.check(
            "acknowledges the reset",
            nack.is_none(),
            format!(
                "{} reset acknowledged on --acknowledge-reset: {}",
                board_words::reset_cause(reset.cause),
                answer(nack)
            ),
        );
    }
    let since = s.statuses.len().saturating_sub(1);
    let Some(mut row) = s.wait_for(since, 1.0, |_| true)? else {
        return Err(TeleopError::NoStatus("after the Hello"));
    };
    if row.status.state == RobotState::Fault {
        let text = start::latched_fault_text(&row.status.fault);
        if !options.clear_fault {
            return Err(TeleopError::Faulted(text));
        }
        println!("{text}: clearing it (--clear-fault)");
        let since = s.statuses.len();
        let nack = s.request(MasterToBoard::ClearFault, 1.0)?;
        let cleared = match nack {
            None => s.wait_for(since, 1.0, |st| st.state != RobotState::Fault)?,
            Some(_) => None,
        };
        let Some(cleared) = cleared else {
            return Err(TeleopError::Faulted(format!(
                "{text}; ClearFault answered {}: the fault stays",
                answer(nack)
            )));
        };
        checks.check(
            "clears the fault",
            true,
            format!(
                "{} cleared on --clear-fault; now {}",
                start::fault_text(&row.status.fault),
                board_words::state(cleared.status.state)
            ),
        );
        row = cleared;
    }
    if let Some(text) = start::busy_text(row.status.state) {
        return Err(TeleopError::Busy(text));
    }
    Ok(row.status.state == RobotState::Ready && !row.status.warnings.contains(Warnings::NOT_HOMED))
}

/// The way out of every run, whatever ended it (the end of the script, an error, a
/// signal): unless the last status shows the drives off (`Boot`, `Disabled`, `Ready`),
/// `Disable` is sent and its answer waited for at most [`DISABLE_TIMEOUT_S`]. What it came
/// to, in words (None: nothing to do).
pub fn disable_on_exit(s: &mut Session) -> Option<String> {
    s.stop = None;
    let state = s.last_status().map(|r| r.status.state);
    if matches!(
        state,
        Some(RobotState::Boot | RobotState::Disabled | RobotState::Ready)
    ) || s.hello.is_none()
    {
        return None;
    }
    s.phase("disable on exit");
    Some(match s.request(MasterToBoard::Disable, DISABLE_TIMEOUT_S) {
        Ok(None) => format!(
            "robot disabled on the way out (was {})",
            state.map_or("unknown", board_words::state)
        ),
        Ok(Some(r)) => format!("Disable on the way out refused: {}", board_words::reason(r)),
        Err(e) => format!("Disable on the way out: {e}"),
    })
}

/// Homing: Ack, then `Ready` without `NOT_HOMED` at the central configuration `central`.
pub fn home(
    s: &mut Session,
    checks: &mut Checks,
    timeout_s: f64,
    central_q: &[f64; 6],
) -> Result<bool, TeleopError> {
    s.phase("home");
    let t0 = s.now_s();
    let since = s.statuses.len();
    let nack = s.request(MasterToBoard::Home { rehome: false }, 1.0)?;
    let row = match nack {
        None => s
            .wait_for(since, timeout_s, |st| {
                (st.state == RobotState::Ready && !st.warnings.contains(Warnings::NOT_HOMED))
                    || st.state == RobotState::Fault
            })?
            .filter(|r| r.status.state == RobotState::Ready),
        Some(_) => None,
    };
    let Some(row) = row else {
        let last = s.last_status().map(|r| r.status);
        checks.check(
            "homes",
            false,
            format!(
                "reply {}; not Ready within {timeout_s} s (last state {}, fault {})",
                answer(nack),
                last.map_or("unknown", |l| board_words::state(l.state)),
                last.map_or("unknown".into(), |l| faults_text(&l.fault))
            ),
        );
        return Ok(false);
    };
    let st = row.status;
    let leg_err = (0..3)
        .map(|j| (f64::from(st.joints[j]) - central_q[j]).abs())
        .fold(0.0, f64::max);
    let link_err = (3..6)
        .map(|j| (f64::from(st.joints[j]) - central_q[j]).abs())
        .fold(0.0, f64::max);
    let p = position(&st);
    checks.check(
        "homes",
        st.faults.is_empty(),
        format!(
            "Ready and homed after {:.2} s; parked {} (legs) and {:.4} deg (links) from the central joints; pose [{:.3}, {:.3}, {:.3}] mm",
            row.t_s - t0,
            mm(leg_err),
            link_err.to_degrees(),
            p.x * 1e3,
            p.y * 1e3,
            p.z * 1e3
        ),
    );
    Ok(true)
}

/// Enable: Ack and `Enabled`.
pub fn enable(s: &mut Session, checks: &mut Checks) -> Result<bool, TeleopError> {
    s.phase("enable");
    let since = s.statuses.len();
    let nack = request_enable(s)?;
    let row = s.wait_for(since, 1.0, |st| st.state == RobotState::Enabled)?;
    let ok = nack.is_none() && row.is_some();
    checks.check("enables", ok, format!("reply {}", answer(nack)));
    Ok(ok)
}

/// Sends `Enable`, again while the board answers `Busy` (the stop that ends homing or a
/// disable still applies the brakes: about 100 ms), for at most a second; the last refusal.
fn request_enable(s: &mut Session) -> Result<Option<NackReason>, TeleopError> {
    let end = s.now_s() + 1.0;
    loop {
        let nack = s.request(MasterToBoard::Enable, 1.0)?;
        if nack != Some(NackReason::Busy) || s.now_s() >= end {
            return Ok(nack);
        }
        s.wait(0.05)?;
    }
}

/// Streams `traj` at `rate_hz`, then settles; checks the tracking.
pub fn stream(
    s: &mut Session,
    checks: &mut Checks,
    traj: &Trajectory,
    passes: &[Pass],
    rate_hz: f64,
    max_deviation_m: f64,
) -> Result<(), TeleopError> {
    let phase = s.phase("path");
    let first_target = s.targets.len();
    let t0 = s.now_s();
    let n = (traj.end_s() * rate_hz).ceil() as usize;
    for k in 0..=n {
        let t = (k as f64 / rate_hz).min(traj.end_s());
        s.poll_until(t0 + k as f64 / rate_hz)?;
        if let Some(pose) = traj.pose(t) {
            s.send_target(&pose)?;
        }
    }
    s.wait(0.3)?;
    let sent = s.targets.get(first_target..).unwrap_or_default().to_vec();
    let rows = s.phase_rows(phase);
    let tracking = Tracking::of(&rows, &sent, t0, passes);
    for (v, (name, _, _)) in tracking.per_pass.iter().zip(passes) {
        let (rms, max) = rms_max(v);
        println!(
            "    {name}: deviation RMS {} max {} ({} statuses)",
            mm(rms),
            mm(max),
            v.len()
        );
    }
    let (p_rms, p_max) = rms_max(&tracking.position);
    let (a_rms, a_max) = rms_max(&tracking.angle);
    let left = rows
        .iter()
        .find(|r| r.status.state != RobotState::Enabled || !r.status.faults.is_empty());
    let nacks: Vec<NackReason> = s
        .refused
        .iter()
        .filter(|r| r.phase == phase)
        .map(|r| r.reason)
        .collect();
    // Late targets (the emulator's host stalled the link or a tick) may be refused as
    // stale, a few; nothing else.
    let stale = nacks
        .iter()
        .filter(|r| **r == NackReason::StaleTarget)
        .count();
    let nacks_ok = stale == nacks.len() && stale * 100 <= sent.len();
    let ok =
        left.is_none() && nacks_ok && !tracking.position.is_empty() && p_max <= max_deviation_m;
    checks.check(
        "follows the path within the tracking limits",
        ok,
        format!(
            "{} targets over {:.1} s at {rate_hz} Hz, {} statuses; deviation from the streamed path: position RMS {} max {} (limit {}), orientation RMS {:.4} deg max {:.4} deg; mean lag {:.1} ms; targets refused {} ({stale} stale, at most 1 % allowed){}; {}",
            sent.len(),
            traj.end_s(),
            rows.len(),
            mm(p_rms),
            mm(p_max),
            mm(max_deviation_m),
            a_rms.to_degrees(),
            a_max.to_degrees(),
            tracking.lag_mean_s() * 1e3,
            nacks.len(),
            nacks
                .first()
                .map_or(String::new(), |r| format!(" (first: {})", board_words::reason(*r))),
            enabled_text(left, rows.last(), t0)
        ),
    );
    Ok(())
}

/// The deviations of the measured poses from the streamed path.
struct Tracking {
    /// Position, m; angle, rad; lag, s: one per status with a measured pose and targets
    /// in its window.
    position: Vec<f64>,
    angle: Vec<f64>,
    lag: Vec<f64>,
    /// The position deviations within each pass.
    per_pass: Vec<Vec<f64>>,
}

impl Tracking {
    /// The deviations of the statuses `rows` from the targets `sent` (the path started at
    /// `t0`), also sorted into `passes`.
    fn of(rows: &[StatusRow], sent: &[(f64, Pose<f64>)], t0: f64, passes: &[Pass]) -> Self {
        let mut t = Tracking {
            position: Vec::new(),
            angle: Vec::new(),
            lag: Vec::new(),
            per_pass: vec![Vec::new(); passes.len()],
        };
        for r in rows {
            let Some(m) = measured_pose(&r.status) else {
                continue;
            };
            if let Some(d) = deviation(sent, r.t_s, 0.25, &m) {
                t.position.push(d.position_m);
                t.angle.push(d.angle_rad);
                t.lag.push(d.lag_s);
                let t_path = r.t_s - t0;
                for (v, (_, a, b)) in t.per_pass.iter_mut().zip(passes) {
                    if (*a..=*b).contains(&t_path) {
                        v.push(d.position_m);
                    }
                }
            }
        }
        t
    }

    /// The mean lag, s (0 without any).
    fn lag_mean_s(&self) -> f64 {
        if self.lag.is_empty() {
            0.0
        } else {
            self.lag.iter().sum::<f64>() / self.lag.len() as f64
        }
    }
}

/// Whether the board stayed Enabled: when and how it `left` (time from `t0`), or its tick
/// timing from the `last` status.
fn enabled_text(left: Option<&StatusRow>, last: Option<&StatusRow>, t0: f64) -> String {
    match left {
        Some(r) => format!(
            "LEFT Enabled at {:.2} s: state {}, fault {}",
            r.t_s - t0,
            board_words::state(r.status.state),
            faults_text(&r.status.fault)
        ),
        None => match last {
            Some(r) => format!(
                "stayed Enabled without fault; board tick worst exec {} us, worst jitter {} us",
                r.status.tick_exec_max_us, r.status.tick_jitter_max_us
            ),
            None => "no status".into(),
        },
    }
}

/// A target outside the workspace: refused (at once, or by the path check after its
/// Ack), the robot holds; then a valid target is followed again.
pub fn refuse(s: &mut Session, checks: &mut Checks, centre: &Pose<f64>) -> Result<(), TeleopError> {
    let phase = s.phase("out-of-workspace target");
    // The robot first finishes the path (it may lag after the emulator was stalled).
    settle(s, 3.0)?;
    let Some((before, refused_before)) = s
        .last_status()
        .map(|r| (position(&r.status), r.status.targets_refused))
    else {
        return Err(TeleopError::NoStatus("before the out-of-workspace target"));
    };
    let outside = Pose {
        t: centre.t + Vector3::new(0.030, 0.0, 0.0),
        r: centre.r,
    };
    let seq = s.send_target(&outside)?;
    let reply = s.reply(seq, 1.0)?;
    s.wait(1.0)?;
    let rows = s.phase_rows(phase);
    let moved = max_displacement(rows.iter(), &before);
    let left = rows
        .iter()
        .find(|r| r.status.state != RobotState::Enabled || !r.status.faults.is_empty());
    let refused_after = rows
        .last()
        .map_or(refused_before, |r| r.status.targets_refused);
    let refused = refused_after.saturating_sub(refused_before);
    // The board's own words for it: at once (the reply) or from its path check.
    let words = s
        .refused
        .iter()
        .rev()
        .find(|r| r.phase == phase)
        .map(|r| r.words.clone())
        .unwrap_or_default();
    let reply_text = match reply {
        master_link::BoardToMaster::Nack { reason, .. } => {
            format!("refused: {}", board_words::reason(reason))
        }
        master_link::BoardToMaster::TargetRefused(_) => format!("refused: {words}"),
        _ => format!("acknowledged, then refused by the board's path check: {words}"),
    };
    checks.check(
        "a target outside the workspace is refused and the robot holds",
        moved < 0.05e-3 && left.is_none() && refused >= 1 && words.starts_with("workspace x"),
        format!(
            "target 30 mm beyond the task box in x; reply {reply_text}; status targets_refused +{refused}; largest displacement over the next 1.0 s {}; {}",
            mm(moved),
            if left.is_none() { "still Enabled, no fault".to_string() } else { "LEFT Enabled".to_string() }
        ),
    );
    // A valid target is still followed.
    let t_step = s.now_s();
    let near = Pose {
        t: centre.t + Vector3::new(0.001, 0.0, 0.0),
        r: centre.r,
    };
    let tol = 0.05e-3;
    let since = s.statuses.len();
    let n1 = s.request_target(&near)?;
    let arrived = s.wait_for(since, 1.5, |st| (position(st) - near.t).norm() < tol)?;
    let since = s.statuses.len();
    let n2 = s.request_target(centre)?;
    let back = s.wait_for(since, 1.5, |st| (position(st) - centre.t).norm() < tol)?;
    let last = s
        .last_status()
        .map_or(f64::NAN, |r| (position(&r.status) - centre.t).norm());
    checks.check(
        "follows again after the refusal",
        arrived.is_some() && back.is_some() && n1.is_none() && n2.is_none(),
        format!(
            "1 mm step and back: replies {} / {}; within {} of the step after {}, of the centre after {}; final distance {}",
            answer(n1),
            answer(n2),
            mm(tol),
            arrived.map_or("never".into(), |r| format!("{:.2} s", r.t_s - t_step)),
            back.map_or("never".into(), |r| format!("{:.2} s", r.t_s - t_step)),
            mm(last)
        ),
    );
    Ok(())
}

/// A valid `Heartbeat` frame with protocol version `version` (CRC correct).
fn frame_with_version(seq: u16, version: u8) -> Result<Vec<u8>, TeleopError> {
    let frame = |what: &str| TeleopError::Frame(what.into());
    let mut buf = [0u8; MAX_FRAME_LEN];
    let header = Header { session: 0, seq };
    let n = encode(&MasterToBoard::Heartbeat, header, &mut buf)
        .map_err(|e| TeleopError::Frame(format!("{e:?}")))?;
    let enc = buf
        .get_mut(..n.saturating_sub(1))
        .ok_or_else(|| frame("frame"))?;
    let raw_len = cobs::decode_in_place(enc).ok_or_else(|| frame("cobs"))?;
    let mut raw = enc.get(..raw_len).ok_or_else(|| frame("raw"))?.to_vec();
    let content = raw_len.checked_sub(CRC_LEN).ok_or_else(|| frame("short"))?;
    if let Some(v) = raw.first_mut() {
        *v = version;
    }
    let crc = CRC32.checksum(raw.get(..content).ok_or_else(|| frame("content"))?);
    raw.truncate(content);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0u8; cobs::max_encoded_len(raw.len()) + 1];
    let m = cobs::encode(&raw, &mut out).ok_or_else(|| frame("cobs encode"))?;
    out.truncate(m);
    out.push(0);
    Ok(out)
}

/// Writes five kinds of bad input to the link: noise, a frame with a byte flipped, a frame
/// of another protocol version, an oversized run of bytes, a replayed sequence number;
/// the bytes sent (the two whole frames counted as 40).
fn send_garbage(s: &mut Session) -> Result<usize, TeleopError> {
    // 1: 100 random non-zero bytes, then a delimiter (malformed or bad checksum).
    let mut x: u32 = 0x1234_5678;
    let mut noise: Vec<u8> = (0..100)
        .map(|_| {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((x >> 24) as u8).max(1)
        })
        .collect();
    noise.push(0);
    s.link.write_raw(&noise)?;
    // 2: a valid frame with one byte flipped (bad checksum or malformed).
    let mut buf = [0u8; MAX_FRAME_LEN];
    let header = Header {
        session: s.link.session(),
        seq: s.link.next_seq(),
    };
    let n = encode(&MasterToBoard::Heartbeat, header, &mut buf)
        .map_err(|e| TeleopError::Frame(format!("{e:?}")))?;
    let mut bad = buf.get(..n).unwrap_or_default().to_vec();
    if let Some(b) = bad.get_mut(n / 2) {
        *b = if *b == 0xFF { 0x7F } else { *b ^ 0x80 | 1 };
    }
    s.link.write_raw(&bad)?;
    // 3: a frame of another protocol version.
    s.link.write_raw(&frame_with_version(
        s.link.next_seq(),
        PROTOCOL_VERSION.wrapping_add(7),
    )?)?;
    // 4: 300 non-zero bytes: longer than any frame (oversized).
    let mut long = vec![0x55u8; 300];
    long.push(0);
    s.link.write_raw(&long)?;
    // 5: a replayed sequence number (out of order).
    let old = s.link.next_seq().wrapping_sub(20);
    s.link.send_with_seq(&MasterToBoard::Heartbeat, old)?;
    Ok(noise.len() + bad.len() + long.len() + 40)
}

/// Garbage on the link: counted by the board (its link counters in the status) and
/// ignored (still Enabled, holding, answering).
pub fn garbage(s: &mut Session, checks: &mut Checks) -> Result<(), TeleopError> {
    let phase = s.phase("garbage");
    s.wait(0.2)?;
    let Some(before) = s.last_status().map(|r| r.status) else {
        return Err(TeleopError::NoStatus("before the garbage"));
    };
    let p0 = position(&before);
    let sent_bytes = send_garbage(s)?;
    s.wait(0.5)?;
    // The link still works: a request is answered.
    let seq = s.send(MasterToBoard::Heartbeat)?;
    let answered = matches!(
        s.reply(seq, 1.0),
        Ok(master_link::BoardToMaster::Ack { .. })
    );
    s.wait(0.1)?;
    let Some(after) = s.last_status().map(|r| r.status) else {
        return Err(TeleopError::NoStatus("after the garbage"));
    };
    let rows = s.phase_rows(phase);
    let moved = max_displacement(rows.iter(), &p0);
    let (a, b) = (after.link, before.link);
    let d = |x: u32, y: u32| x.wrapping_sub(y);
    let rejected = d(a.rejected(), b.rejected());
    let left = rows
        .iter()
        .find(|r| r.status.state != RobotState::Enabled || !r.status.faults.is_empty());
    checks.check(
        "garbage on the link is counted and ignored",
        rejected >= 5
            && d(a.out_of_order, b.out_of_order) >= 1
            && d(a.oversized, b.oversized) >= 1
            && d(a.wrong_version, b.wrong_version) >= 1
            && answered
            && left.is_none()
            && moved < 0.05e-3
            && after.warnings.contains(Warnings::LINK_ERRORS),
        format!(
            "5 bad frames sent ({} bytes); board counters: rejected +{rejected} (bad checksum +{}, malformed +{}, oversized +{}, wrong version +{}, out of order +{}), frames ok +{}; LINK_ERRORS warning {}; next request acknowledged {answered}; {}; largest displacement {}",
            sent_bytes,
            d(a.bad_checksum, b.bad_checksum),
            d(a.malformed, b.malformed),
            d(a.oversized, b.oversized),
            d(a.wrong_version, b.wrong_version),
            d(a.out_of_order, b.out_of_order),
            d(a.frames_ok, b.frames_ok),
            after.warnings.contains(Warnings::LINK_ERRORS),
            if left.is_none() { "still Enabled, no fault" } else { "LEFT Enabled" },
            mm(moved)
        ),
    );
    Ok(())
}

/// The heartbeat stops: the board holds (`HEARTBEAT_LATE`, safe operating stop, no
/// motion) after ~100 ms, and after ~500 ms latches `HeartbeatTimeout` and stops as SS1
/// (brakes, then torque off; still homed); then heartbeats resume, the master clears the
/// fault and enables again.
pub fn heartbeat_loss(s: &mut Session, checks: &mut Checks) -> Result<(), TeleopError> {
    s.wait(0.2)?;
    let phase = s.phase("heartbeat stopped");
    s.heartbeat = false;
    let t_stop = s.last_beat_s;
    let p0 = s
        .last_status()
        .map(|r| position(&r.status))
        .unwrap_or_else(Vector3::zeros);
    s.wait(1.2)?;
    let rows = s.phase_rows(phase);
    let hold = rows.iter().find(|r| {
        r.status.warnings.contains(Warnings::HEARTBEAT_LATE)
            || r.status.state != RobotState::Enabled
    });
    let off = rows.iter().find(|r| r.status.state == RobotState::Fault);
    let moved = max_displacement(rows.iter(), &p0);
    let end = rows.last().map(|r| r.status);
    let t = |r: Option<&StatusRow>| r.map(|r| r.t_s - t_stop);
    let (th, toff) = (t(hold), t(off));
    let ok = th.is_some_and(|x| (0.08..=0.25).contains(&x))
        && toff.is_some_and(|x| (0.45..=0.75).contains(&x))
        && off.is_some_and(|r| r.status.fault.cause == FaultCause::HeartbeatTimeout)
        && end.is_some_and(|e| {
            !e.warnings.contains(Warnings::NOT_HOMED) && e.stop == StopStatus::SafeStop1Done
        })
        && moved < 0.05e-3;
    checks.check(
        "when the heartbeat stops the firmware holds, then stops with brakes",
        ok,
        format!(
            "after the last heartbeat: hold (HEARTBEAT_LATE) seen at {} ms, fault ({}, stop at the end {}) at {} ms (status every 20 ms; limits 100 / 500 ms); largest displacement {}; still homed {}",
            th.map_or("never".into(), |x| format!("{:.0}", x * 1e3)),
            off.map_or("none", |r| r.status.fault.cause.name()),
            end.map_or("unknown", |e| board_words::stop(RobotState::Fault, e.stop)
                .unwrap_or("none")),
            toff.map_or("never".into(), |x| format!("{:.0}", x * 1e3)),
            mm(moved),
            end.is_some_and(|e| !e.warnings.contains(Warnings::NOT_HOMED))
        ),
    );
    s.phase("heartbeat resumed");
    s.heartbeat = true;
    s.wait(0.2)?;
    let since = s.statuses.len();
    let cleared = s.request(MasterToBoard::ClearFault, 1.0)?;
    let nack = match cleared {
        None => request_enable(s)?,
        refused => refused,
    };
    let row = s.wait_for(since, 1.0, |st| {
        st.state == RobotState::Enabled && !st.warnings.contains(Warnings::HEARTBEAT_LATE)
    })?;
    checks.check(
        "enables again once the heartbeat is back",
        nack.is_none() && row.is_some(),
        format!(
            "reply {}; Enabled without HEARTBEAT_LATE: {}",
            answer(nack),
            row.is_some()
        ),
    );
    s.wait(0.3)?;
    Ok(())
}

/// Disable: drives off, still homed (`Ready`).
pub fn disable(s: &mut Session, checks: &mut Checks) -> Result<(), TeleopError> {
    s.phase("disable");
    let since = s.statuses.len();
    let nack = s.request(MasterToBoard::Disable, 1.0)?;
    let row = s.wait_for(since, 1.0, |st| st.state == RobotState::Ready)?;
    checks.check(
        "disables",
        nack.is_none() && row.is_some(),
        format!(
            "reply {}; drives off (Ready, still homed): {}",
            answer(nack),
            row.is_some()
        ),
    );
    Ok(())
}

/// A request's answer in words: accepted, or refused with the reason.
fn answer(nack: Option<NackReason>) -> String {
    match nack {
        None => "accepted".into(),
        Some(r) => format!("refused: {}", board_words::reason(r)),
    }
}

/// The status's latched fault in words ("following error on leg 2: error 1.20 mm"), or
/// "none".
fn faults_text(f: &master_link::FaultRecord) -> String {
    board_words::fault(f).unwrap_or_else(|| "none".into())
}
