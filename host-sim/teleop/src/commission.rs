//! Commissioning from the master's side: the board's commissioning mode
//! (`control::commissioning`) run joint by joint over a [`Session`], each joint's record
//! read once its test has ended, and each record in words (what was measured, each finding
//! and the fix it implies). `host-sim commission` runs it with a person at the robot; the
//! emulated board's test (`host-sim/board-scenarios`) runs the same function on the board's
//! release image.

use std::fmt::Write as _;

use master_link::{CommissionFindings as F, CommissionRecord, FaultCause, NackReason, RobotState};

use crate::session::Session;
use crate::TeleopError;

/// The joints' short names, joint order.
pub const NAMES: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// The test's stated limits, as the person at the robot reads them
/// (`control::commissioning::CommissionConfig::reference`).
pub const LIMITS: &str = "each joint moves at most 3 mm (a leg) or 3 deg (a link); the push stops \
                          once anything has moved 1.5 mm or 1.5 deg, and at 90 % of the motor's \
                          continuous rating; then the joint is driven back to where it started";

/// How long a joint's test may take on the board's clock, s: the board's phases take
/// 1.47 s at most (offset 0.05, applied push 0.04, release 0.06, push 0.6, settle 0.06,
/// return 0.6, settle 0.06: `CommissionConfig::reference`), several times that.
pub const JOINT_TIMEOUT_S: f64 = 10.0;

/// Why commissioning stopped.
#[derive(Debug, thiserror::Error)]
pub enum CommissionError {
    /// The board refused the test.
    #[error("the board refused commissioning: {}{}", board_words::reason(*.0), refusal_hint(*.0))]
    Refused(NackReason),
    /// A joint's test did not end in time.
    #[error("{}: the board's test did not end within {JOINT_TIMEOUT_S} s", name(*.0))]
    Timeout(u8),
    /// The board's monitors stopped a joint's test.
    #[error("{}: the board stopped with a fault: {cause:?} on joint {fault_joint} (value {value}); the monitors stopped the test: find its cause (host-sim faultlog) before going on", name(*.joint))]
    Fault {
        /// The joint under test.
        joint: u8,
        /// The fault's cause.
        cause: FaultCause,
        /// The joint the fault names.
        fault_joint: u8,
        /// Its value.
        value: f32,
    },
    /// The link.
    #[error(transparent)]
    Teleop(#[from] TeleopError),
}

fn name(j: u8) -> &'static str {
    NAMES.get(usize::from(j)).copied().unwrap_or("?")
}

fn refusal_hint(reason: NackReason) -> &'static str {
    match reason {
        NackReason::AlreadyHomed | NackReason::Faulted => {
            " (the robot is homed or has a fault latched: once a person at the robot \
             confirms it may move, run again with --confirm)"
        }
        NackReason::Busy => " (the board is homing, stopping or testing a joint)",
        _ => "",
    }
}

/// The person at the robot, as commissioning asks them.
pub trait Person {
    /// Joint `joint` is about to move (the instructions are printed): returns once the
    /// joint is clear.
    fn ready(&mut self, joint: u8);
    /// Without a second position channel a reversed direction may be the motor's or the
    /// encoder's: did `joint` move towards +q? `None`: nobody to ask (the finding stays
    /// "motor or encoder").
    fn moved_towards_plus(&mut self, joint: u8) -> Option<bool>;
    /// Shows a line of text.
    fn say(&mut self, text: &str);
}

/// Nobody at the robot: nothing is asked (scripts, tests); the text is dropped.
#[derive(Debug, Default)]
pub struct Unattended;

impl Person for Unattended {
    fn ready(&mut self, _joint: u8) {}
    fn moved_towards_plus(&mut self, _joint: u8) -> Option<bool> {
        None
    }
    fn say(&mut self, _text: &str) {}
}

/// Tests `joints` one after the other (the first enters the commissioning mode, with
/// `confirm` when the robot is homed or has a fault latched), each record once its test
/// has ended; then disables the drives (out of the mode). The session has said hello.
pub fn run(
    s: &mut Session,
    joints: &[u8],
    confirm: bool,
    person: &mut dyn Person,
) -> Result<Vec<CommissionRecord>, CommissionError> {
    let mut records = Vec::with_capacity(joints.len());
    let mut confirm = confirm;
    for &j in joints {
        let words = board_words::joint_name(j).unwrap_or_default();
        person.say("");
        person.say(&format!(
            "{} ({words}): watch it; it will be pushed {} (towards +q), then back.",
            name(j),
            if j < 3 {
                "to extend"
            } else {
                "counter-clockwise seen from above"
            }
        ));
        person.ready(j);
        let mut rec = s
            .commission(j, confirm, 2.0)?
            .map_err(CommissionError::Refused)?;
        // Only the first joint enters the mode; the confirmation is not needed again.
        confirm = false;
        let end = s.now_s() + JOINT_TIMEOUT_S;
        while !rec.done {
            if s.now_s() > end {
                return Err(CommissionError::Timeout(j));
            }
            s.wait(0.05)?;
            if let Some(st) = s.last_status() {
                if st.status.state == RobotState::Fault {
                    let f = st.status.fault;
                    return Err(CommissionError::Fault {
                        joint: j,
                        cause: f.cause,
                        fault_joint: f.joint,
                        value: f.value,
                    });
                }
            }
            rec = s
                .commission(j, false, 2.0)?
                .map_err(CommissionError::Refused)?;
        }
        if rec.findings.contains(F::DIRECTION_MISMATCH) {
            if let Some(plus) = person.moved_towards_plus(j) {
                rec.findings = F(rec.findings.0 & !F::DIRECTION_MISMATCH.0);
                rec.findings.insert(if plus {
                    F::ENCODER_REVERSED
                } else {
                    F::MOTOR_REVERSED
                });
            }
        }
        person.say(joint_text(&rec).trim_end());
        records.push(rec);
    }
    // Drives off, out of the commissioning mode.
    let _ = s.request(master_link::MasterToBoard::Disable, 1.0)?;
    Ok(records)
}

/// A value of joint `j` at the edge (mm, deg).
fn edge(j: usize, x: f32) -> String {
    let x = f64::from(x);
    if x.is_nan() {
        return "-".into();
    }
    if j < 3 {
        format!("{:.3} mm", x * 1e3)
    } else {
        format!("{:.3} deg", x.to_degrees())
    }
}

/// One joint's result in words: what was measured, each finding and its fix.
pub fn joint_text(r: &CommissionRecord) -> String {
    let j = usize::from(r.joint).min(5);
    let mut t = String::new();
    let moved = match r.moved_encoder {
        255 => "none".to_string(),
        k => NAMES[usize::from(k).min(5)].to_string(),
    };
    let _ = writeln!(
        t,
        "  {}: encoder that moved {moved} ({}), reference {} ({}), scale {}, current offset {:.3} A, current while moving {:.3} A, push {:.3} duty at breakaway, largest travel {:.0} % of the limit",
        NAMES[j],
        edge(usize::from(r.moved_encoder).min(5), r.encoder_motion),
        if r.reference { "second channel" } else { "none" },
        edge(j, r.reference_motion),
        if r.scale.is_nan() { "-".to_string() } else { format!("{:.4}", r.scale) },
        r.current_offset_a,
        r.current_a,
        r.breakaway_duty,
        f64::from(r.peak_travel) * 100.0,
    );
    if r.findings.is_empty() {
        let _ = writeln!(t, "  {}: OK (wired as the pin map says)", NAMES[j]);
    }
    for f in F::ALL {
        if r.findings.contains(f) {
            let (what, fix) = board_words::commission_finding(f);
            let _ = writeln!(t, "  {}: FOUND {what}", NAMES[j]);
            let _ = writeln!(t, "  {}:   fix: {fix}", NAMES[j]);
            if f == F::SCALE {
                let _ = writeln!(
                    t,
                    "  {}:   measured counts per unit / profile's = {:.4}",
                    NAMES[j], r.scale
                );
            }
            if f == F::ENCODER_SWAPPED {
                let _ = writeln!(
                    t,
                    "  {}:   its motion was counted on {moved}'s counter",
                    NAMES[j]
                );
            }
        }
    }
    t
}

/// The commissioning report: every joint's result.
pub fn report_text(records: &[CommissionRecord]) -> String {
    let mut t = String::from("commissioning report (host-sim commission)\n");
    let _ = writeln!(t, "limits: {LIMITS}\n");
    for r in records {
        t.push_str(&joint_text(r));
    }
    let found = records.iter().filter(|r| !r.findings.is_empty()).count();
    let _ = writeln!(
        t,
        "\n{} joint(s) tested, {found} with findings",
        records.len()
    );
    t
}
