//! The master paths of the chain benchmarks (`chain_bench.rs` on the simulated board in
//! lockstep, `chain_on_board.rs` on a board served on a socket): the hand's pose and
//! buttons in, the sample the teleoperation mapping gets out, through a scripted position
//! master, UDP datagrams, or a SpaceMouse behind this module's own spacenavd side
//! (protocol 1: handshake, client name, device queries); and
//! the clutch scenario both play after the session.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use masters::pose::{rotate, rotation_increment};
use masters::rate::{Deflection, RateMapping, RateMappingConfig};
use masters::spacenav::{
    SpaceNavMaster, SpnavDeviceInfo, SpnavOptions, REQ_CHANGE_PROTO, REQ_DEV_NAXES,
    REQ_DEV_NBUTTONS, REQ_DEV_TYPE, REQ_DEV_USBID, REQ_SET_NAME, REQ_TAG,
};
use masters::udp::{
    GateConfig, PoseDatagram, UdpPoseMaster, BUTTON_CLUTCH, BUTTON_OPERATOR_PRESENT,
    FLAG_TRACKING_VALID,
};
use masters::{CartesianPose, Master, MasterInput, MasterSample, OperatorButtons};
use nalgebra::Vector3;
use std::io::{Read, Write};
use std::net::UdpSocket;
use std::os::unix::net::{UnixListener, UnixStream};
use std::time::{Duration, Instant};

/// The stream rate, Hz.
pub const FS: f64 = 100.0;

/// How long a loopback datagram or socket write may take to arrive before the test
/// fails: a failure detector only, no figure depends on it.
pub const DELIVERY_LIMIT: Duration = Duration::from_secs(10);

/// Polls `master` at `t_s` until `done` holds for its sample.
pub fn poll_until(
    master: &mut dyn Master,
    t_s: f64,
    done: impl Fn(&MasterSample) -> bool,
) -> MasterSample {
    let end = Instant::now() + DELIVERY_LIMIT;
    loop {
        if let Some(s) = master.poll(t_s).unwrap() {
            if done(&s) {
                return s;
            }
        }
        assert!(Instant::now() < end, "{} delivered nothing", master.name());
        std::thread::sleep(Duration::from_micros(50));
    }
}

/// A master path: the hand's pose and buttons at `t_s` in, the mapping's sample out.
#[allow(clippy::large_enum_variant)] // three values, made once each
pub enum MasterPath {
    Scripted,
    Udp {
        tx: UdpSocket,
        master: UdpPoseMaster,
        sequence: u32,
    },
    SpaceMouse {
        daemon: UnixStream,
        master: SpaceNavMaster,
        mapping: RateMapping,
        /// The integral of the twists sent, as the mapping forms it.
        integral: CartesianPose,
        last_t: Option<f64>,
        buttons: u32,
        _dir: tempfile::TempDir,
    },
}

/// The rate mapping of the benchmark's SpaceMouse: spacenavd's axes, full deflection
/// 50 mm/s and 45 deg/s (the hand's tremor and voluntary speeds together reach about
/// 27 mm/s and 17 deg/s; the default 10 mm/s would saturate).
pub fn mouse_mapping() -> RateMapping {
    RateMapping::new(RateMappingConfig {
        max_linear_speed_m_s: 0.050,
        max_angular_speed_rad_s: 45f64.to_radians(),
        ..RateMappingConfig::spacemouse_spacenavd()
    })
    .unwrap()
}

impl MasterPath {
    pub fn name(&self) -> &'static str {
        match self {
            MasterPath::Scripted => "scripted",
            MasterPath::Udp { .. } => "udp",
            MasterPath::SpaceMouse { .. } => "spacemouse",
        }
    }

    pub fn udp() -> MasterPath {
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let master = UdpPoseMaster::bind(
            "127.0.0.1:0".parse().unwrap(),
            Some(tx.local_addr().unwrap()),
            GateConfig::default(),
        )
        .unwrap();
        MasterPath::Udp {
            tx,
            master,
            sequence: 0,
        }
    }

    /// A SpaceMouse behind this module's spacenavd side, which speaks protocol 1: it
    /// answers the client's handshake (version 1), takes its name and answers its four
    /// device queries (6 axes, 2 buttons, USB id 046d:c626, device type 0x206) before
    /// the events start.
    pub fn spacemouse() -> MasterPath {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("spnav.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let daemon = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let [hello] = read_words::<1>(&mut s);
            assert_eq!(hello, REQ_TAG | REQ_CHANGE_PROTO | 1, "the handshake word");
            s.write_all(&(REQ_TAG | REQ_CHANGE_PROTO | 1).to_ne_bytes())
                .unwrap();
            let name = read_words::<8>(&mut s);
            assert_eq!(name[0], REQ_TAG | REQ_SET_NAME, "the client's name first");
            for _ in 0..4 {
                let q = read_words::<8>(&mut s);
                let data = match q[0] & 0xffff {
                    REQ_DEV_NAXES => [6, 0, 0, 0, 0, 0, 0],
                    REQ_DEV_NBUTTONS => [2, 0, 0, 0, 0, 0, 0],
                    REQ_DEV_USBID => [0x046d, 0xc626, 0, 0, 0, 0, 0],
                    REQ_DEV_TYPE => [0x206, 0, 0, 0, 0, 0, 0],
                    other => panic!("unexpected request {other:#x}"),
                };
                let mut w = [0i32; 8];
                w[0] = q[0];
                w[1..].copy_from_slice(&data);
                s.write_all(&packet(w)).unwrap();
            }
            s
        });
        let master =
            SpaceNavMaster::connect(&path, &SpnavOptions::default(), mouse_mapping()).unwrap();
        let daemon = daemon.join().unwrap();
        assert_eq!(master.client().protocol(), 1, "protocol 1 agreed");
        assert_eq!(
            master.client().device(),
            Some(SpnavDeviceInfo {
                axes: 6,
                buttons: 2,
                usb_id: Some((0x046d, 0xc626)),
                device_type: Some(0x206),
            })
        );
        MasterPath::SpaceMouse {
            daemon,
            master,
            mapping: mouse_mapping(),
            integral: CartesianPose::identity(),
            last_t: None,
            buttons: 0,
            _dir: dir,
        }
    }

    /// The sample the mapping gets at `t_s` for the hand at `hand` with `buttons`.
    pub fn sample(
        &mut self,
        t_s: f64,
        hand: &CartesianPose,
        buttons: OperatorButtons,
    ) -> MasterSample {
        match self {
            MasterPath::Scripted => MasterSample {
                t_s,
                input: MasterInput::Pose(*hand),
                buttons,
                device_time_us: None,
                deflection: None,
            },
            MasterPath::Udp {
                tx,
                master,
                sequence,
            } => {
                *sequence += 1;
                let q = hand.orientation;
                let d = PoseDatagram {
                    flags: FLAG_TRACKING_VALID,
                    session: 0x5eed,
                    sequence: *sequence,
                    timestamp_us: (t_s * 1e6).round() as u64,
                    position_mm: (hand.position_m * 1e3).map(|x| x as f32).into(),
                    orientation_wxyz: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
                    buttons: (u32::from(buttons.clutch) * BUTTON_CLUTCH)
                        | (u32::from(buttons.operator_present) * BUTTON_OPERATOR_PRESENT),
                };
                let to = master.local_addr().unwrap();
                tx.send_to(&d.encode(), to).unwrap();
                let want = d.timestamp_us;
                let s = poll_until(master, t_s, |s| s.device_time_us == Some(want));
                assert_eq!(master.gate().counts().total(), 0, "datagrams refused");
                s
            }
            MasterPath::SpaceMouse {
                daemon,
                master,
                mapping,
                integral,
                last_t,
                buttons: pressed,
                ..
            } => {
                // The buttons, as the daemon reports them: 0 the clutch, 1 presence.
                let want = u32::from(buttons.clutch) | u32::from(buttons.operator_present) << 1;
                for b in 0..2 {
                    let bit = 1u32 << b;
                    if (want ^ *pressed) & bit != 0 {
                        let kind = if want & bit != 0 { 1 } else { 2 };
                        daemon
                            .write_all(&packet([kind, b, 0, 0, 0, 0, 0, 0]))
                            .unwrap();
                    }
                }
                *pressed = want;
                // The twist whose integral over this tick (as the mapping forms it:
                // the newest twist times the tick) reaches the hand.
                // A tick closer than the stream's period to the last (a host loop
                // catching up after a late tick) is not caught up in it: the hand
                // commands a speed, and what the short tick leaves is carried over.
                let dt = last_t.map_or(1.0 / FS, |t0| t_s - t0);
                *last_t = Some(t_s);
                let over = dt.max(1.0 / FS);
                let v = (hand.position_m - integral.position_m) / over;
                let w = rotation_increment(&integral.orientation, &hand.orientation) / over;
                let axes = deflection_for(mapping.config(), &[v.x, v.y, v.z, w.x, w.y, w.z]);
                let (tw, stats) = mapping.twist(&Deflection {
                    axes: axes.map(f64::from),
                    buttons: want,
                });
                assert_eq!(stats.saturated_axes, 0, "the cap saturated at {t_s} s");
                integral.position_m += tw.linear_m_s * dt;
                integral.orientation = rotate(&integral.orientation, &(tw.angular_rad_s * dt));
                let [x, y, z, rx, ry, rz] = axes;
                daemon
                    .write_all(&packet([0, x, y, z, rx, ry, rz, 10]))
                    .unwrap();
                let sent = axes.map(f64::from);
                poll_until(master, t_s, |s| {
                    s.deflection == Some(sent)
                        && s.buttons.clutch == buttons.clutch
                        && s.buttons.operator_present == buttons.operator_present
                })
            }
        }
    }
}

/// `N` words from the client, host order.
fn read_words<const N: usize>(s: &mut UnixStream) -> [i32; N] {
    let mut out = [0i32; N];
    for w in &mut out {
        let mut b = [0u8; 4];
        s.read_exact(&mut b).unwrap();
        *w = i32::from_ne_bytes(b);
    }
    out
}

pub fn packet(words: [i32; 8]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_ne_bytes()).collect()
}

/// The device counts that make the rate mapping `c` give the robot-frame twist `g`
/// (m/s, rad/s): per robot axis, the inverse of its deadzone and expo, rounded to counts,
/// on the device axis the map names.
pub fn deflection_for(c: &RateMappingConfig, g: &[f64; 6]) -> [i32; 6] {
    let mut axes = [0i32; 6];
    for (k, s) in c.axis_map.iter().enumerate() {
        let vmax = if k < 3 {
            c.max_linear_speed_m_s
        } else {
            c.max_angular_speed_rad_s
        };
        let want = g[k] / vmax;
        let target = want.abs();
        // (1 − e) x + e x³ = |g| / vmax, increasing in x: Newton from x = target.
        let mut x = target.min(1.0);
        for _ in 0..30 {
            let f = (1.0 - c.expo) * x + c.expo * x * x * x - target;
            let df = (1.0 - c.expo) + 3.0 * c.expo * x * x;
            x -= f / df;
        }
        let n = if target > 0.0 {
            (c.deadzone + x * (1.0 - c.deadzone)).copysign(want)
        } else {
            0.0
        };
        let n = if s.invert { -n } else { n };
        axes[s.axis.index()] = (n * c.full_scale).round() as i32;
    }
    axes
}

/// The clutch scenario after the session: following, the clutch pressed while the hand
/// makes a 4 mm stroke, released, then a 3 mm stroke followed.
pub const CLUTCH_FOLLOW_S: f64 = 0.5;
pub const CLUTCH_HELD_S: f64 = 1.0;
pub const CLUTCH_AFTER_S: f64 = 1.5;

/// The extra stroke of the clutch scenario `t` s after the session's end, m.
pub fn clutch_strokes(t: f64) -> Vector3<f64> {
    let mj = |tau: f64| {
        let tau = tau.clamp(0.0, 1.0);
        tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau))
    };
    let during = mj((t - CLUTCH_FOLLOW_S - 0.1) / 0.8);
    let after = mj((t - CLUTCH_FOLLOW_S - CLUTCH_HELD_S - 0.2) / 1.0);
    Vector3::new(0.004 * during, 0.003 * after, 0.0)
}

/// After the session, the tremor goes on this long with the hand still, then stops at
/// once, s.
pub const TREMOR_ON_S: f64 = 0.3;
/// Then the hand stays still this long without tremor, s (before the clutch scenario).
pub const STILL_S: f64 = 1.2;

/// The tremor's size at `ts` s of the session: amplitude `A` on x, `0.8 A` on y,
/// `0.6 A` on z (`masters::synthetic`), together `√2·A`, m.
pub fn tremor_bound_m(ts: f64) -> f64 {
    masters::synthetic::SyntheticOperator::tremor_amplitude_m(ts) * (1.0f64 + 0.64 + 0.36).sqrt()
}

/// How far the board's setpoint may be from the still hand `dt` s after the tremor
/// stopped at once, its size then `bound_m` (the derivation is in `chain_on_board.rs`'s
/// documentation): `bound_m·(1 + x)·e^{−x} + 2 µm`, `x = μ1·fs·(dt − 0.05 s)`.
pub fn tremor_stop_envelope_m(bound_m: f64, dt: f64) -> f64 {
    let mu1 = masters::canceller::CancellerConfig::default().amplitude_gain;
    let x = mu1 * FS * (dt - 0.05).max(0.0);
    bound_m * (1.0 + x) * (-x).exp() + 2e-6
}
