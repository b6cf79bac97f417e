//! From reset to the link: the boot and the 1 kHz tick with the IWDG fed, the pins as the
//! image configures them, Hello.

use master_link::{BoardToMaster, ResetCause, ResetStatus, PROTOCOL_VERSION};

use super::{addr, ms, Run, ScenarioError};
use crate::master::SESSION_NONCE;
use board_emulator::bench::{Action, Recorded};
use board_emulator::pins::{expected_configuration, PinConfig};

use super::wiring::{gpio_base, EXTI_IMR, EXTI_RTSR};

/// Boot: the first control tick, then 1 kHz ticks with the IWDG fed every tick (0.1..0.3 s).
pub fn tick(run: &mut Run) -> Result<(), ScenarioError> {
    let uart4 = run.symbols.uart4;
    run.act(Action::WatchInstruction(uart4));
    {
        let mut rig = run.rig.lock();
        rig.run_until(rigless::time::VirtualNanos(300_000_000), false)?;
    }
    run.act(Action::UnwatchInstruction(uart4));
    let (hits, recorded): (Vec<u64>, Vec<Recorded>) = {
        let mut rig = run.rig.lock();
        let hits = std::mem::take(&mut rig.bench.hits)
            .into_iter()
            .filter(|(_, a)| *a == uart4)
            .map(|(t, _)| t.0)
            .collect();
        (hits, std::mem::take(&mut rig.bench.recorded))
    };
    let first_tick = hits.first().copied();
    // The IWDG is started (0xCCCC) when the control task starts.
    let iwdg_start = recorded
        .iter()
        .find(|r| r.write && r.address == addr::IWDG_KR && r.value == 0xCCCC)
        .map(|r| r.at.0);
    let window = 100_000_000..300_000_000;
    let ticks: Vec<u64> = hits
        .iter()
        .copied()
        .filter(|t| window.contains(t))
        .collect();
    let gaps: Vec<u64> = ticks.windows(2).map(|w| w[1] - w[0]).collect();
    let (gap_min, gap_max) = (
        gaps.iter().copied().min().unwrap_or(0),
        gaps.iter().copied().max().unwrap_or(0),
    );
    let feeds: Vec<u64> = recorded
        .iter()
        .filter(|r| r.write && r.address == addr::IWDG_KR && r.value == 0xAAAA)
        .map(|r| r.at.0)
        .collect();
    let feeds_window = feeds.iter().filter(|t| window.contains(*t)).count();
    let feed_gap = feeds
        .windows(2)
        .map(|w| w[1] - w[0])
        .max()
        .unwrap_or(u64::MAX);
    let ok = first_tick.is_some()
        && (199..=201).contains(&ticks.len())
        && gap_max <= 1_010_000
        && gap_min >= 990_000
        && iwdg_start.is_some()
        && (199..=201).contains(&feeds_window)
        && feed_gap <= 1_100_000;
    let opt = |t: Option<u64>| t.map_or("never".to_string(), ms);
    run.check(
        "boots to the 1 kHz control tick with the IWDG fed every tick",
        ok,
        format!(
            "IWDG started (control task running) at {}, first control interrupt (UART4 executor) at {}; 0.1..0.3 s: {} ticks, period {:.1}..{:.1} us; {feeds_window} IWDG feeds (0xAAAA to IWDG_KR), longest gap between feeds {:.1} us (timeout 10 ms)",
            opt(iwdg_start),
            opt(first_tick),
            ticks.len(),
            gap_min as f64 / 1e3,
            gap_max as f64 / 1e3,
            feed_gap as f64 / 1e3
        ),
    );
    Ok(())
}

/// The pins: every one configured by the image as the board's map says (mode, alternate
/// function, pull), and the e-stop line routed (SYSCFG, EXTI).
pub fn pins(run: &mut Run) -> Result<(), ScenarioError> {
    let mut addresses = Vec::new();
    for port in &run.wiring.ports {
        let base = gpio_base(*port);
        // MODER, PUPDR, AFRL, AFRH (RM0090 rev 19 section 8.4).
        addresses.extend([base, base + 0x0C, base + 0x20, base + 0x24]);
    }
    let (exticr, shift) = run.wiring.estop_exticr();
    addresses.extend([exticr, EXTI_IMR, EXTI_RTSR]);
    run.act(Action::Peek(addresses));
    run.wait(0.001)?;
    let peeked = std::mem::take(&mut run.rig.lock().bench.peeked);
    let reg = |a: u64| {
        peeked
            .iter()
            .find(|(x, _)| *x == a)
            .and_then(|(_, v)| *v)
            .unwrap_or(0)
    };
    let mut wrong = Vec::new();
    let expected = expected_configuration(&run.wiring.target.map);
    for (pin, want, what) in &expected {
        let base = gpio_base(pin.port);
        let n = u64::from(pin.number);
        let mode = (reg(base) >> (2 * n)) & 0b11;
        let pull = (reg(base + 0x0C) >> (2 * n)) & 0b11;
        let afr = if n < 8 {
            reg(base + 0x20)
        } else {
            reg(base + 0x24)
        };
        let af = (afr >> (4 * (n % 8))) & 0xF;
        let ok = match want {
            PinConfig::Output => mode == 0b01,
            PinConfig::InputPullUp => mode == 0b00 && pull == 0b01,
            PinConfig::Alternate(x) => mode == 0b10 && af == u64::from(*x),
            PinConfig::Analog => mode == 0b11,
        };
        if !ok {
            wrong.push(format!(
                "{pin} ({what}): want {want:?}, MODER {mode:02b} PUPDR {pull:02b} AF {af}"
            ));
        }
    }
    // The e-stop pin on its EXTI line (its EXTICR field = its port), rising edge, unmasked.
    let estop = run.wiring.estop;
    let line = u32::from(run.wiring.estop_line());
    let routed = (reg(exticr) >> shift) & 0xF == estop.port.index() as u64;
    let rising = reg(EXTI_RTSR) & (1 << line) != 0;
    let unmasked = reg(EXTI_IMR) & (1 << line) != 0;
    run.check(
        "the image configures every pin as the board's pin map says",
        wrong.is_empty() && routed && rising && unmasked,
        format!(
            "{}: {} pins checked (GPIOx_MODER, PUPDR, AFRL/H of ports {}): {}; e-stop {estop} routed to EXTI{line} {routed}, rising edge {rising}, unmasked {unmasked}",
            run.wiring.target.name,
            expected.len(),
            run.wiring.ports.iter().map(|p| p.letter()).collect::<String>(),
            if wrong.is_empty() {
                "all as mapped".to_string()
            } else {
                format!("{} differ: {}", wrong.len(), wrong.join("; "))
            }
        ),
    );
    Ok(())
}

/// Hello -> HelloReply with a session the board issued (not 0), the master's nonce echoed
/// and the reset cause (PowerOn, needs no acknowledgement), then a Status every 20 ms.
pub fn hello(run: &mut Run) -> Result<(), ScenarioError> {
    teleop::ci::hello(&mut run.s, &mut run.ci, 1.0)?;
    run.adopt_teleop_checks();
    let reply = run.rig.lock().last_hello();
    let since = run.s.statuses.len();
    run.wait(0.2)?;
    let n = run.s.statuses.len() - since;
    let ok = matches!(
        reply,
        Some((_, BoardToMaster::HelloReply { protocol_version, session, nonce, reset, .. }))
            if protocol_version == PROTOCOL_VERSION
                && session != 0
                && nonce == SESSION_NONCE
                && reset == ResetStatus { cause: ResetCause::PowerOn, acknowledged: true }
    );
    run.check(
        "HelloReply carries the board's session, the nonce and the reset cause PowerOn; a Status every 20 ms",
        ok && (9..=11).contains(&n),
        format!(
            "{}; master's nonce {SESSION_NONCE:#010x}; {n} statuses in 0.2 s",
            reply.map_or("no HelloReply".to_string(), |(t, r)| format!(
                "at {t:.4} s: {r:?}"
            ))
        ),
    );
    Ok(())
}
