//! The stops as the pins show them: heartbeat loss (SS2 hold, then SS1), Disable while
//! moving (SS1), the e-stop edge (the interrupt's STO within 10 µs), the safety relay's
//! feedback disagreeing with the button, a driver's nFAULT (STO).

use master_link::{
    FaultCause, MasterToBoard, NackReason, RobotState, StopStatus, Warnings, NO_JOINT,
};

use super::{addr, mm, position, Run, ScenarioError};
use board_emulator::bench::{Action, Recorded};
use board_emulator::mechanics::Surroundings;

use super::wiring::{OutputPin, Wiring};

/// The firmware's brake engage time (`control::stops::StopConfig`, as the board's
/// `reference_config_for` takes it): SS1 keeps the drives on this long after applying the
/// brakes, ns.
pub fn brake_engage_ns() -> u64 {
    control::stops::StopConfig::default().brake_engage_us * 1_000
}

/// When the firmware applied the brakes (its first writes of the brake pins' `BRn` to their
/// `GPIOx_BSRR`, both done) and when it first took the driver enable low, ns: the pins'
/// changes at their exact instants (RM0090 rev 19 section 8.4.7).
fn brakes_then_drivers(w: &Wiring, writes: &[Recorded]) -> (Option<u64>, Option<u64>) {
    let first = |pin: OutputPin| {
        writes
            .iter()
            .find(|r| pin.written(r.address, r.value, false))
            .map(|r| r.at.0)
    };
    let brakes = first(w.brakes[0])
        .zip(first(w.brakes[1]))
        .map(|(a, b)| a.max(b));
    (brakes, first(w.driver_enable))
}

/// `BR11, BR12` / `BR10`-style names of the brakes' and the driver enable's resets.
fn names(w: &Wiring) -> (String, String) {
    (
        format!("{}, {}", w.brakes[0].name(false), w.brakes[1].name(false)),
        w.driver_enable.name(false),
    )
}

fn ms(t: Option<u64>, from: u64) -> String {
    t.map_or("never".into(), |t| {
        format!("{:.3} ms", t.saturating_sub(from) as f64 / 1e6)
    })
}

/// The SS1 ordering on the pins: brakes applied, then the drivers off at least the brake
/// engage time later. (ok, figures)
fn ss1_order(w: &Wiring, writes: &[Recorded], from: u64) -> (bool, String) {
    let (b, d) = brakes_then_drivers(w, writes);
    let (brakes, enable) = names(w);
    let gap = b.zip(d).map(|(b, d)| d as i64 - b as i64);
    let engage = brake_engage_ns();
    let ok = gap.is_some_and(|g| g >= i64::try_from(engage).unwrap_or(i64::MAX));
    (
        ok,
        format!(
            "brake pins low ({brakes}) at {}, driver enable low ({enable}) at {}: {} later (the firmware's brake engage time: {} ms)",
            ms(b, from),
            ms(d, from),
            gap.map_or("-".into(), |g| format!("{:.3} ms", g as f64 / 1e6)),
            engage as f64 / 1e6
        ),
    )
}

/// Heartbeat loss (teleop's step and check: hold, then HeartbeatTimeout, then enabled
/// again), and on the pins: the hold keeps the drives on (SS2, safe operating stop), the
/// timeout stops as SS1 with the brakes applied before the drivers go off.
pub fn heartbeat_loss(run: &mut Run) -> Result<(), ScenarioError> {
    run.wait(0.1)?;
    let _ = run.take_edges();
    let _ = run.take_pin_writes();
    let since = run.s.statuses.len();
    let t0 = run.now_ns();
    teleop::ci::heartbeat_loss(&mut run.s, &mut run.ci)?;
    run.adopt_teleop_checks();
    let edges = run.take_edges();
    let writes = run.take_pin_writes();
    let rows = run.rows_since(since);
    let hold = rows.iter().find(|r| {
        r.status.warnings.contains(Warnings::HEARTBEAT_LATE)
            && matches!(
                r.status.stop,
                StopStatus::SafeStop2Decelerating | StopStatus::SafeOperatingStop
            )
    });
    let fault = rows
        .iter()
        .find(|r| r.status.fault.cause == FaultCause::HeartbeatTimeout);
    let stops: Vec<StopStatus> = rows.iter().fold(Vec::new(), |mut v, r| {
        if v.last() != Some(&r.status.stop) {
            v.push(r.status.stop);
        }
        v
    });
    let drives_on_in_hold = hold.is_some_and(|h| {
        let t = (h.t_s * 1e9) as u64;
        // Still enabled at the hold's status: no edge took the enable low before it.
        !edges.iter().any(|(e, o)| e.0 <= t && !o.driver_enable)
    });
    let (order_ok, order) = ss1_order(&run.wiring, &writes, t0);
    run.check(
        "heartbeat loss: SS2 hold with the drives on, then HeartbeatTimeout as SS1, brakes before the drivers",
        hold.is_some() && drives_on_in_hold && fault.is_some() && order_ok,
        format!(
            "hold (HEARTBEAT_LATE, {:?}) in the status at {}, drives still on; fault {:?} at {}; stops in turn {:?}; {order}",
            hold.map(|h| h.status.stop),
            ms(hold.map(|h| (h.t_s * 1e9) as u64), t0),
            fault.map(|f| f.status.fault.cause),
            ms(fault.map(|f| (f.t_s * 1e9) as u64), t0),
            stops
        ),
    );
    Ok(())
}

/// Disable while the robot moves along a line at 10 mm/s: SS1 (decelerate under power,
/// brakes, torque off), homing kept.
pub fn disable_while_moving(run: &mut Run) -> Result<(), ScenarioError> {
    let (_, limits) = super::master_settings()?;
    let start = run
        .last_status()
        .and_then(|s| teleop::ci::measured_pose(&s))
        .unwrap_or(run.centre);
    let end = kinematics_core::Pose {
        t: start.t + nalgebra::Vector3::new(-0.010, 0.0, 0.0),
        r: start.r,
    };
    let mut traj = trajectory::Trajectory::default();
    traj.push(trajectory::line(&limits, &start, &end, 10.0));
    let rate = super::motion::STREAM_RATE_HZ;
    let t0 = run.now_s();
    let mut disabled_at = None;
    let mut reply = None;
    let _ = run.take_pin_writes();
    let since = run.s.statuses.len();
    for k in 0.. {
        let t = f64::from(k) / rate;
        run.s.poll_until(t0 + t)?;
        if t >= 0.5 {
            disabled_at = Some(run.now_ns());
            reply = Some(run.s.request(MasterToBoard::Disable, 1.0)?);
            break;
        }
        if let Some(pose) = traj.pose(t) {
            run.s.send_target(&pose)?;
        }
    }
    let from = disabled_at.unwrap_or(0);
    let at_disable = run.last_status().map(|s| position(&s));
    let row = run.wait_for(since, 1.0, |s| {
        s.state == RobotState::Ready && s.stop == StopStatus::None
    })?;
    run.wait(0.1)?;
    let writes = run.take_pin_writes();
    let rows = run.rows_since(since);
    let after: Vec<_> = rows
        .iter()
        .filter(|r| (r.t_s * 1e9) as u64 >= from)
        .collect();
    let stops: Vec<StopStatus> = after.iter().fold(Vec::new(), |mut v, r| {
        if v.last() != Some(&r.status.stop) {
            v.push(r.status.stop);
        }
        v
    });
    let speed_before = {
        let moving: Vec<_> = rows
            .iter()
            .filter(|r| (r.t_s * 1e9) as u64 <= from)
            .collect();
        match moving.as_slice() {
            [.., a, b] if b.t_s > a.t_s => {
                (position(&b.status) - position(&a.status)).norm() / (b.t_s - a.t_s)
            }
            _ => 0.0,
        }
    };
    let travel = at_disable.map_or(f64::NAN, |p| {
        after
            .iter()
            .map(|r| (position(&r.status) - p).norm())
            .fold(0.0, f64::max)
    });
    let writes: Vec<Recorded> = writes.into_iter().filter(|w| w.at.0 >= from).collect();
    let (order_ok, order) = ss1_order(&run.wiring, &writes, from);
    let sequence_ok = stops.contains(&StopStatus::SafeStop1Decelerating)
        || stops.contains(&StopStatus::SafeStop1Braking);
    let homed = row.is_some_and(|r| !r.status.warnings.contains(Warnings::NOT_HOMED));
    run.check(
        "Disable while moving: SS1, decelerate under power, brakes, then torque off (still homed)",
        reply == Some(None) && row.is_some() && sequence_ok && order_ok && homed && travel < 1e-3,
        format!(
            "moving at {:.1} mm/s when Disable was sent; reply {}; stops in turn {:?}; Ready, the stop over, after {}; travel after the request {}; {order}",
            speed_before * 1e3,
            match reply {
                Some(None) => "Ack".to_string(),
                Some(Some(r)) => format!("Nack {r:?}"),
                None => "none".into(),
            },
            stops,
            ms(row.map(|r| (r.t_s * 1e9) as u64), from),
            mm(travel),
        ),
    );
    let nack = run.enable()?;
    run.check(
        "enables again after the Disable",
        nack.is_none(),
        format!("reply {nack:?}"),
    );
    Ok(())
}

/// The e-stop edge 20 µs into a control tick: its EXTI interrupt (`EXTI15_10` on both boards) forces every output
/// safe (driver enable low, brakes applied, every PWM compare output forced inactive)
/// within 10 µs, preempting the control interrupt, which resumes after; STO in the status.
pub fn estop(run: &mut Run) -> Result<(), ScenarioError> {
    run.wait(0.05)?;
    let (uart4, exti) = (run.symbols.uart4, run.symbols.estop_handler);
    let w = run.wiring.clone();
    {
        let mut rig = run.rig.lock();
        rig.bench.hits.clear();
        rig.bench.recorded.clear();
        rig.bench.estop_edge = None;
    }
    run.act(Action::WatchInstruction(exti));
    run.act(Action::EstopAfterInstruction {
        address: uart4,
        delay_ns: 20_000,
        record_ns: 2_000_000,
    });
    run.wait(0.01)?;
    run.act(Action::UnwatchInstruction(exti));
    // The driver pressed the button at the edge.
    run.surroundings.estop_pressed = true;
    let since = run.s.statuses.len();
    run.wait(0.06)?;
    let (edge, recorded, hits, outputs) = {
        let mut rig = run.rig.lock();
        (
            rig.bench.estop_edge.take(),
            std::mem::take(&mut rig.bench.recorded),
            std::mem::take(&mut rig.bench.hits),
            rig.bench.last.outputs,
        )
    };
    let Some((t_edge, t_tick)) = edge.map(|(e, a)| (e.0, a.0)) else {
        run.check("e-stop", false, "the e-stop edge never came".into());
        return Ok(());
    };
    let t_isr = hits
        .iter()
        .find(|(t, a)| *a == exti && t.0 >= t_edge)
        .map(|(t, _)| t.0);
    let after: Vec<&Recorded> = recorded.iter().filter(|r| r.at.0 >= t_edge).collect();
    let reset = |pin: OutputPin| {
        after
            .iter()
            .find(|r| r.write && pin.written(r.address, r.value, false))
            .map(|r| r.at.0)
    };
    // BRn of the driver enable and of both brakes: RM0090 rev 19 section 8.4.7.
    let t_enable = reset(w.driver_enable);
    let t_brakes = reset(w.brakes[0])
        .zip(reset(w.brakes[1]))
        .map(|(a, b)| a.max(b));
    // OCxM = 100 (force inactive) in each PWM timer's CCMR1, RM0090 rev 19 section 19.4.7.
    let forced = |v: u64, two: bool| (v >> 4) & 7 == 0b100 && (!two || (v >> 12) & 7 == 0b100);
    let kills: Vec<u64> = w
        .pwm_ccmr1
        .iter()
        .filter_map(|(_, a, two)| {
            after
                .iter()
                .find(|r| r.write && r.address == *a && forced(r.value, *two))
                .map(|r| r.at.0)
        })
        .collect();
    let t_safe = if kills.len() == w.pwm_ccmr1.len() {
        kills.iter().copied().chain(t_enable).chain(t_brakes).max()
    } else {
        None
    };
    let cyc_before = recorded
        .iter()
        .filter(|r| !r.write && r.address == addr::DWT_CYCCNT && (t_tick..t_edge).contains(&r.at.0))
        .count();
    let cyc_after = t_safe.map_or(0, |s| {
        recorded
            .iter()
            .filter(|r| {
                !r.write
                    && r.address == addr::DWT_CYCCNT
                    && r.at.0 > s
                    && r.at.0 < t_tick + 1_000_000
            })
            .count()
    });
    let latency = t_safe.map(|s| s - t_edge);
    let outputs_safe = !outputs.driver_enable
        && outputs.brakes_released == [false, false]
        && outputs.duty.iter().all(|d| *d == 0.0);
    let row = run.rows_since(since).into_iter().find(|r| {
        r.status.state == RobotState::Fault
            && r.status.fault.cause == FaultCause::EmergencyStopButton
    });
    let sto = row.is_some_and(|r| r.status.stop == StopStatus::SafeTorqueOff);
    let us = |t: Option<u64>| {
        t.map_or("never".to_string(), |t| {
            format!("{:.3} us", t.saturating_sub(t_edge) as f64 / 1e3)
        })
    };
    run.check(
        "the e-stop edge takes the outputs safe within 10 us, preempting the control interrupt",
        latency.is_some_and(|l| l <= 10_000)
            && t_isr.is_some()
            && cyc_before >= 1
            && cyc_after >= 1
            && outputs_safe
            && sto,
        format!(
            "{} edge {:.1} us into a control tick; {} entered after {}, driver enable low ({}) after {}, brakes applied ({}) after {}, every PWM compare output forced inactive (CCMR1 OCxM = 100 on {}: {} of {}) by {}: safe after {}; the interrupted tick read DWT_CYCCNT {cyc_before}x before the edge and {cyc_after}x after the kill (it resumed); pins 60 ms later: enable {}, brakes released {:?}, duties {:?}; status {:?} cause {:?}, stop {:?}",
            w.estop,
            (t_edge - t_tick) as f64 / 1e3,
            w.estop_handler(),
            us(t_isr),
            names(&w).1,
            us(t_enable),
            names(&w).0,
            us(t_brakes),
            w.pwm_ccmr1.iter().map(|(t, _, _)| t.name()).collect::<Vec<_>>().join("/"),
            kills.len(),
            w.pwm_ccmr1.len(),
            us(kills.iter().copied().max()),
            us(t_safe),
            outputs.driver_enable,
            outputs.brakes_released,
            outputs.duty,
            row.map(|r| r.status.state),
            row.map(|r| r.status.fault.cause),
            row.map(|r| r.status.stop),
        ),
    );
    // Release, clear.
    let released = Surroundings {
        estop_pressed: false,
        ..run.surroundings
    };
    run.set_surroundings(released);
    run.wait(0.05)?;
    let since = run.s.statuses.len();
    let nack = run.s.request(MasterToBoard::ClearFault, 0.5)?;
    let ready = run.wait_for(since, 0.5, |s| s.state == RobotState::Ready)?;
    run.check(
        "after the e-stop is released, ClearFault returns to Ready (still homed)",
        nack.is_none() && ready.is_some_and(|r| !r.status.warnings.contains(Warnings::NOT_HOMED)),
        format!("reply {nack:?}; Ready: {}", ready.is_some()),
    );
    Ok(())
}

/// The safety relay open with the button released (a failed relay, a cut feedback wire):
/// Enable refused (`SafetyRelayMismatch`), then the fault once the disagreement outlasts the
/// relay's switching time; the safety chain is not trusted again in this power cycle, so
/// `ClearFault` stays refused after the relay agrees again (the last scenario of a run).
pub fn relay_mismatch(run: &mut Run) -> Result<(), ScenarioError> {
    let t0 = run.now_ns();
    let since = run.s.statuses.len();
    let stuck = Surroundings {
        relay_stuck_open: true,
        ..run.surroundings
    };
    run.set_surroundings(stuck);
    // The relay has been open for 3 ms (3 ticks have read it) when the master asks.
    run.wait(0.003)?;
    let nack = run.s.request(MasterToBoard::Enable, 0.5)?;
    let replied = run.now_ns();
    let fault = run.wait_for(since, 0.2, |s| {
        s.fault.cause == FaultCause::SafetyRelayMismatch
    })?;
    run.check(
        "the relay feedback disagreeing with the button: Enable refused (SafetyRelayMismatch), then the fault",
        nack == Some(NackReason::SafetyRelayMismatch)
            && fault.is_some_and(|f| f.status.stop == StopStatus::SafeTorqueOff),
        format!(
            "relay open, button released at 0 ms; Enable sent at 3 ms, answered {nack:?} at {}; fault {:?} (value {:?}: 2 = open without the button) with {:?} in the status at {}",
            ms(Some(replied), t0),
            fault.map(|f| f.status.fault.cause),
            fault.map(|f| f.status.fault.value),
            fault.map(|f| f.status.stop),
            ms(fault.map(|f| (f.t_s * 1e9) as u64), t0),
        ),
    );
    let fixed = Surroundings {
        relay_stuck_open: false,
        ..run.surroundings
    };
    run.set_surroundings(fixed);
    run.wait(0.05)?;
    let since = run.s.statuses.len();
    let nack = run.s.request(MasterToBoard::ClearFault, 0.5)?;
    let still = run.wait_for(since, 0.2, |s| s.state == RobotState::Fault)?;
    run.check(
        "the relay agreeing again, ClearFault is still refused (the relay test needs a power cycle)",
        nack == Some(NackReason::FaultStillActive) && still.is_some(),
        format!("reply {nack:?}; still Fault: {}", still.is_some()),
    );
    Ok(())
}

/// A driver's nFAULT while enabled: DriverFault, STO (the drivers off and the brakes
/// applied at once, within a tick of the pin).
pub fn driver_fault(run: &mut Run) -> Result<(), ScenarioError> {
    let nack = run.enable()?;
    run.wait(0.1)?;
    let _ = run.take_pin_writes();
    let since = run.s.statuses.len();
    let t0 = run.now_ns();
    let mut failed = run.surroundings;
    failed.driver_failed[2] = true;
    run.set_surroundings(failed);
    let row = run.wait_for(since, 0.2, |s| s.state == RobotState::Fault)?;
    let writes = run.take_pin_writes();
    let (b, d) = brakes_then_drivers(&run.wiring, &writes);
    let together = b.zip(d).is_some_and(|(b, d)| b.abs_diff(d) <= 10_000);
    let prompt = d.is_some_and(|d| d - t0 <= 2_000_000);
    let st = row.map(|r| r.status);
    run.check(
        "a driver's nFAULT while enabled: DriverFault with STO, drivers off and brakes applied at once",
        nack.is_none()
            && st.is_some_and(|s| {
                s.fault.cause == FaultCause::DriverFault && s.stop == StopStatus::SafeTorqueOff
            })
            && together
            && prompt,
        format!(
            "enable {nack:?}; driver l3 latched a fault at 0 ms (nFAULT {} low from the next plant step, 0.1 ms); driver enable low ({}) at {}, brake pins low ({}) at {}; status fault {:?} (joint {}), stop {:?}",
            run.wiring.target.map.driver_fault,
            names(&run.wiring).1,
            ms(d, t0),
            names(&run.wiring).0,
            ms(b, t0),
            st.map(|s| s.fault.cause),
            st.map_or("-".into(), |s| if s.fault.joint == NO_JOINT {
                "none".to_string()
            } else {
                s.fault.joint.to_string()
            }),
            st.map(|s| s.stop),
        ),
    );
    let mut fixed = run.surroundings;
    fixed.driver_failed = [false; 6];
    run.set_surroundings(fixed);
    run.wait(0.05)?;
    let since = run.s.statuses.len();
    let nack = run.s.request(MasterToBoard::ClearFault, 0.5)?;
    let ready = run.wait_for(since, 0.5, |s| s.state == RobotState::Ready)?;
    run.check(
        "the driver fault gone, ClearFault returns to Ready",
        nack.is_none() && ready.is_some(),
        format!("reply {nack:?}; Ready: {}", ready.is_some()),
    );
    Ok(())
}
