//! The readable summary `host-sim sim` prints after a run: the settings, the timing, the
//! pose errors and the lag (overall and per phase), the accuracy verdict, the step
//! responses, the actuators' peaks, the supervisor's counters and the servo's fault.

use crate::metrics::{self, LagSummary, PoseErrorSummary};
use crate::run::Summary;
use std::fmt::Write;

/// The readable summary printed after a run.
pub fn report_text(s: &Summary) -> String {
    let mut o = String::new();
    settings(&mut o, s);
    timing(&mut o, s);
    errors(&mut o, s);
    phases(&mut o, s);
    accuracy_and_steps(&mut o, s);
    actuators(&mut o, s);
    supervisor(&mut o, s);
    servo_fault(&mut o, s);
    o
}

/// The scenario, the rates, the backlash and the tool.
fn settings(o: &mut String, s: &Summary) {
    let st = &s.settings;
    let _ = writeln!(o, "sim {}: {}", s.scenario, s.description);
    let _ = writeln!(
        o,
        "  control {} Hz, plant step {:.0} us, leg backlash {:.3} mm, compensation {}, tool {}",
        st.control_rate_hz,
        st.plant_step_us,
        st.leg_backlash_mm,
        if st.backlash_compensation {
            "on"
        } else {
            "off"
        },
        match st.payload_attached_at_s {
            Some(t) => format!(
                "{} kg on {:?} mm from {} s",
                st.payload_mass_kg, st.payload_lever_mm, t
            ),
            None => "none".into(),
        }
    );
}

/// Simulated against wall-clock time, and where the time of a tick went.
fn timing(o: &mut String, s: &Summary) {
    let tm = &s.timing;
    let parts = format!(
        "controller servo half {:.1}, plant {:.1}, truth+payload {:.1} (payload {:.1}), \
         other {:.1}",
        tm.controller_us, tm.plant_us, tm.truth_and_payload_us, tm.payload_us, tm.other_us
    );
    let _ = if tm.threads >= 2 {
        writeln!(
            o,
            "  simulated {:.2} s in {:.2} s: {:.0}x real time on 2 threads ({:.1} us per tick; \
             master side: supervisor {:.1}; drive side: {parts})",
            s.simulated_s, s.wall_s, s.speed_up, tm.per_tick_us, tm.planner_us
        )
    } else {
        writeln!(
            o,
            "  simulated {:.2} s in {:.2} s: {:.0}x real time on 1 thread ({:.1} us per tick: \
             supervisor {:.1}, {parts})",
            s.simulated_s, s.wall_s, s.speed_up, tm.per_tick_us, tm.planner_us
        )
    };
}

/// A pose error's tip and orientation figures.
fn pose_error(p: &PoseErrorSummary) -> String {
    format!(
        "tip RMS {:.4} mm, max {:.4} mm; orientation RMS {:.4} deg, max {:.4} deg",
        p.tip_rms_mm, p.tip_max_mm, p.orientation_rms_deg, p.orientation_max_deg
    )
}

/// The setpoint's lag behind the stream ("-" when not measured).
fn lag(l: &Option<LagSummary>) -> String {
    l.map_or("-".to_string(), |l| {
        format!(
            "{:.1} ms{} (setpoint vs delayed stream RMS {:.4} mm; at no delay {:.4} mm)",
            l.delay_ms,
            if l.delay_ms < 0.0 { ", ahead" } else { "" },
            l.rms_at_delay_mm,
            l.rms_at_zero_mm
        )
    })
}

/// The tracking and target errors and the lag over the whole run.
fn errors(o: &mut String, s: &Summary) {
    let _ = writeln!(
        o,
        "  tracking error (true vs setpoint): {}",
        pose_error(&s.tracking)
    );
    let _ = writeln!(
        o,
        "  target error (true vs master):     {}",
        pose_error(&s.target)
    );
    let _ = writeln!(
        o,
        "  lag of the setpoint behind the master's stream (best-fitting delay): {}",
        lag(&s.supervisor.lag)
    );
}

/// Each phase's errors and lag, and where its stream asks more than the limits allow.
fn phases(o: &mut String, s: &Summary) {
    for p in &s.phases {
        let _ = writeln!(
            o,
            "  {}: tracking tip RMS {:.4} / max {:.4} mm; vs target RMS {:.4} / max {:.4} mm; lag {}",
            p.name,
            p.tracking.tip_rms_mm,
            p.tracking.tip_max_mm,
            p.target.tip_rms_mm,
            p.target.tip_max_mm,
            lag(&p.lag)
        );
        if let Some(b) = p
            .beyond_limits
            .as_ref()
            .filter(|b| !b.intervals_s.is_empty())
        {
            let spans: Vec<String> = b
                .intervals_s
                .iter()
                .map(|[a, z]| format!("{a:.3}-{z:.3}"))
                .collect();
            let _ = writeln!(
                o,
                "    the stream asks more than the tip acceleration limit ({} m/s²; peak {:.3}) at {} s: the limits do not allow the path there; target error elsewhere (without {} s after each) RMS {:.4} mm over {:.0} % of the phase",
                b.tip_accel_limit_m_s2,
                b.peak_accel_m_s2,
                spans.join(", "),
                metrics::CATCH_UP_S,
                b.target_rms_elsewhere_mm,
                b.elsewhere_share * 100.0
            );
        }
    }
}

/// The accuracy verdict and the step responses.
fn accuracy_and_steps(o: &mut String, s: &Summary) {
    if let Some(a) = &s.accuracy {
        let _ = writeln!(
            o,
            "  accuracy target ({}): tip RMS {:.4} mm (<= {}), max {:.4} mm (<= {}): {}",
            a.judged_on,
            a.tip_rms_mm,
            a.limit_tip_rms_mm,
            a.tip_max_mm,
            a.limit_tip_max_mm,
            if a.met { "MET" } else { "NOT MET" }
        );
    }
    for st in &s.steps {
        let _ = writeln!(
            o,
            "  step at {:.2} s ({:.2} mm, {:.2} deg): rise {} s, overshoot {:.4} mm / {:.4} \
             deg, settled within {} mm / {} deg after {} s, final error {:.4} mm",
            st.at_s,
            st.step_mm,
            st.step_deg,
            st.rise_s.map_or("-".into(), |v| format!("{v:.3}")),
            st.overshoot_mm,
            st.overshoot_deg,
            st.settle_band_mm,
            st.settle_band_deg,
            st.settle_s.map_or("never".into(), |v| format!("{v:.3}")),
            st.final_error_mm
        );
    }
}

/// The actuators' peak currents (against nominal) and duties.
fn actuators(o: &mut String, s: &Summary) {
    let cur: Vec<String> = s
        .actuators
        .iter()
        .map(|a| {
            format!(
                "{} {:.2}/{:.2}",
                a.joint, a.peak_current_a, a.nominal_current_a
            )
        })
        .collect();
    let _ = writeln!(o, "  peak/nominal current A: {}", cur.join(", "));
    let duty: Vec<String> = s
        .actuators
        .iter()
        .map(|a| format!("{} {:.2}", a.joint, a.peak_duty))
        .collect();
    let _ = writeln!(o, "  peak duty: {}", duty.join(", "));
}

/// What the supervisor did with the targets: accepted, refused, warned, stopped.
fn supervisor(o: &mut String, s: &Summary) {
    let sv = &s.supervisor;
    let warned: Vec<String> = sv
        .warn_by_guard
        .iter()
        .map(|(g, t)| format!("{g} {t:.2} s"))
        .collect();
    let _ = writeln!(
        o,
        "  supervisor: {} targets sent, {} accepted ({} at once in a certified region, {} of them \
         led), {} refused (path {}, too far {}, stale {}), warn {:.2} s{}, stopped {:.2} s, \
         stops {}{}",
        sv.targets_sent,
        sv.accepted,
        sv.certified,
        sv.led,
        sv.refused.total,
        sv.refused.path,
        sv.refused.too_far,
        sv.refused.stale,
        sv.warn_s,
        if warned.is_empty() {
            String::new()
        } else {
            format!(" ({})", warned.join(", "))
        },
        sv.stopped_s,
        sv.stops,
        sv.refused
            .first_reason
            .as_ref()
            .map(|r| format!("; first refusal: {r}"))
            .unwrap_or_default()
    );
}

/// The servo's fault, if one latched.
fn servo_fault(o: &mut String, s: &Summary) {
    match &s.faults.servo {
        None => {
            let _ = writeln!(o, "  servo faults: none");
        }
        Some(f) => {
            let _ = writeln!(
                o,
                "  servo fault at {:.3} s: {} on {} (error {})",
                f.at_s,
                f.kind,
                f.joint.unwrap_or("-"),
                match (f.error_mm, f.error_deg) {
                    (Some(e), _) => format!("{e:.4} mm"),
                    (_, Some(e)) => format!("{e:.4} deg"),
                    _ => "-".into(),
                }
            );
        }
    }
}
