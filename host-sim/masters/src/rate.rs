//! Rate control for 6-DOF deflection devices (3Dconnexion SpaceMouse): deflection →
//! velocity, and the device's buttons → clutch and operator presence.
//!
//! For each robot axis `k` of the twist `[vx, vy, vz, wx, wy, wz]` (frame {0}):
//!
//! 1. take the device axis the map names for it, with its sign (per-axis swap and sign
//!    into the robot frame);
//! 2. normalise by the full-scale count: `n = raw / full_scale`; beyond full scale the
//!    device saturates at ±1 (counted in [`RateStats::saturated_axes`]);
//! 3. deadzone and gain curve: `d = (|n| − dz) / (1 − dz)` above the deadzone `dz`, 0
//!    inside; `g = (1 − e)·d + e·d³` (the "expo" curve, `e` in [0, 1]: fine control near
//!    the centre, full speed at full deflection);
//! 4. optionally keep only the dominant axis (largest `g`), overall or per group
//!    (one translation and one rotation axis);
//! 5. velocity `sign(n)·g·v_max` (translation) or `sign(n)·g·ω_max` (rotation).

use crate::device::OperatorButtons;
use crate::pose::Twist;
use nalgebra::Vector3;
use thiserror::Error;

/// A device axis, in the order devices report them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DeviceAxis {
    /// Translation x.
    X,
    /// Translation y.
    Y,
    /// Translation z.
    Z,
    /// Rotation about x.
    Rx,
    /// Rotation about y.
    Ry,
    /// Rotation about z.
    Rz,
}

impl DeviceAxis {
    /// Index 0..6 in `[x, y, z, rx, ry, rz]`.
    pub fn index(self) -> usize {
        match self {
            DeviceAxis::X => 0,
            DeviceAxis::Y => 1,
            DeviceAxis::Z => 2,
            DeviceAxis::Rx => 3,
            DeviceAxis::Ry => 4,
            DeviceAxis::Rz => 5,
        }
    }
}

/// Where one robot axis takes its deflection from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisSource {
    /// The device axis.
    pub axis: DeviceAxis,
    /// Use it with the opposite sign.
    pub invert: bool,
}

const fn src(axis: DeviceAxis, invert: bool) -> AxisSource {
    AxisSource { axis, invert }
}

/// Keep only the strongest axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DominantAxis {
    /// All six axes act together.
    Off,
    /// Only the strongest of the six.
    Single,
    /// The strongest translation axis and the strongest rotation axis.
    PerGroup,
}

/// How the operator-present button works.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresenceMode {
    /// Present while the button is held (a true dead-man).
    Hold,
    /// Each press toggles presence (not a dead-man: for bench work only).
    Toggle,
}

/// The rate mapping's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct RateMappingConfig {
    /// Device counts at full deflection (SpaceMouse: about 350).
    pub full_scale: f64,
    /// Deadzone as a fraction of full scale, in [0, 1).
    pub deadzone: f64,
    /// Expo of the gain curve, in [0, 1] (0 linear, 1 cubic).
    pub expo: f64,
    /// Dominant-axis filtering.
    pub dominant: DominantAxis,
    /// For each robot axis `[vx, vy, vz, wx, wy, wz]`, its device axis and sign; every
    /// device axis is used once.
    pub axis_map: [AxisSource; 6],
    /// Linear speed at full deflection, m/s.
    pub max_linear_speed_m_s: f64,
    /// Angular speed at full deflection, rad/s.
    pub max_angular_speed_rad_s: f64,
    /// Device button index of the clutch.
    pub clutch_button: u8,
    /// Device button index of operator presence.
    pub operator_button: u8,
    /// How the operator button works.
    pub presence: PresenceMode,
}

impl RateMappingConfig {
    /// For a SpaceMouse read through **evdev**: the kernel's axes are x to the right, y
    /// towards the user, z down (pushing the cap); the robot's {0} has z up and, with the
    /// device in front of the robot, y away from the user. So robot (x, y, z) = device
    /// (x, −y, −z), and the same for the rotations (a proper rotation, det = +1).
    /// Left button (index 0) = clutch, right button (index 1) = operator present (held).
    /// Full deflection gives 10 mm/s and 15 deg/s.
    pub fn spacemouse_evdev() -> Self {
        use DeviceAxis::*;
        RateMappingConfig {
            full_scale: 350.0,
            deadzone: 0.08,
            expo: 0.5,
            dominant: DominantAxis::Off,
            axis_map: [
                src(X, false),
                src(Y, true),
                src(Z, true),
                src(Rx, false),
                src(Ry, true),
                src(Rz, true),
            ],
            max_linear_speed_m_s: 0.010,
            max_angular_speed_rad_s: 15f64.to_radians(),
            clutch_button: 0,
            operator_button: 1,
            presence: PresenceMode::Hold,
        }
    }

    /// For a SpaceMouse read through **spacenavd** with its default configuration: the
    /// daemon swaps y and z and inverts both (its default axis map is {0, 2, 1, 3, 5, 4}
    /// with inversions {0, 1, 1, 0, 1, 1}), so its frame is x right, y up, z away from
    /// the user, and robot (x, y, z) = daemon (x, z, y), the rotations likewise
    /// (wx, wy, wz) = (rx, rz, ry). A `spnavrc` with `swap-yz` or `invert-*` changes this.
    /// Otherwise as [`RateMappingConfig::spacemouse_evdev`].
    pub fn spacemouse_spacenavd() -> Self {
        use DeviceAxis::*;
        RateMappingConfig {
            axis_map: [
                src(X, false),
                src(Z, false),
                src(Y, false),
                src(Rx, false),
                src(Rz, false),
                src(Ry, false),
            ],
            ..Self::spacemouse_evdev()
        }
    }
}

/// A rate-mapping setting that is not usable.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum RateConfigError {
    /// A number is out of its range.
    #[error("rate mapping: {field} = {value} is outside {range}")]
    OutOfRange {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        range: &'static str,
    },
    /// The axis map uses a device axis twice.
    #[error("rate mapping: device axis {axis:?} is mapped to robot axes {first} and {second}")]
    AxisUsedTwice {
        /// The device axis.
        axis: DeviceAxis,
        /// The robot axes (0..6).
        first: usize,
        /// The second one.
        second: usize,
    },
    /// Clutch and operator presence on the same button.
    #[error("rate mapping: clutch and operator presence both on button {0}")]
    SameButton(u8),
}

/// A device's state: raw axis counts and pressed buttons.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Deflection {
    /// `[x, y, z, rx, ry, rz]`, device counts.
    pub axes: [f64; 6],
    /// Pressed buttons, bit i = button i.
    pub buttons: u32,
}

/// What the mapping did to one deflection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RateStats {
    /// Device axes beyond full scale (saturated at ±1).
    pub saturated_axes: u8,
    /// Axes zeroed by the dominant-axis filter.
    pub suppressed_axes: u8,
}

/// Deflection → twist, buttons → clutch and presence.
#[derive(Clone, Debug)]
pub struct RateMapping {
    config: RateMappingConfig,
    toggled_present: bool,
    last_buttons: u32,
}

fn in_range(
    field: &'static str,
    value: f64,
    ok: bool,
    range: &'static str,
) -> Result<(), RateConfigError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(RateConfigError::OutOfRange {
            field,
            value,
            range,
        })
    }
}

impl RateMapping {
    /// Checks the settings.
    pub fn new(config: RateMappingConfig) -> Result<Self, RateConfigError> {
        let c = &config;
        in_range("full_scale", c.full_scale, c.full_scale > 0.0, "(0, inf)")?;
        in_range(
            "deadzone",
            c.deadzone,
            (0.0..1.0).contains(&c.deadzone),
            "[0, 1)",
        )?;
        in_range("expo", c.expo, (0.0..=1.0).contains(&c.expo), "[0, 1]")?;
        in_range(
            "max_linear_speed_m_s",
            c.max_linear_speed_m_s,
            c.max_linear_speed_m_s > 0.0,
            "(0, inf)",
        )?;
        in_range(
            "max_angular_speed_rad_s",
            c.max_angular_speed_rad_s,
            c.max_angular_speed_rad_s > 0.0,
            "(0, inf)",
        )?;
        let mut used: [Option<usize>; 6] = [None; 6];
        for (k, s) in c.axis_map.iter().enumerate() {
            let slot = &mut used[s.axis.index()];
            if let Some(first) = *slot {
                return Err(RateConfigError::AxisUsedTwice {
                    axis: s.axis,
                    first,
                    second: k,
                });
            }
            *slot = Some(k);
        }
        if c.clutch_button == c.operator_button {
            return Err(RateConfigError::SameButton(c.clutch_button));
        }
        Ok(RateMapping {
            config,
            toggled_present: false,
            last_buttons: 0,
        })
    }

    /// The settings.
    pub fn config(&self) -> &RateMappingConfig {
        &self.config
    }

    /// The twist for a deflection (frame {0}) and what the mapping did.
    pub fn twist(&self, d: &Deflection) -> (Twist, RateStats) {
        let c = &self.config;
        let mut stats = RateStats::default();
        let mut g = [0.0f64; 6];
        for (k, s) in c.axis_map.iter().enumerate() {
            let raw = d.axes[s.axis.index()];
            let mut n = if raw.is_finite() {
                raw / c.full_scale
            } else {
                0.0
            };
            if n.abs() > 1.0 {
                stats.saturated_axes += 1;
                n = n.signum();
            }
            if s.invert {
                n = -n;
            }
            let a = n.abs();
            let v = if a > c.deadzone {
                let x = (a - c.deadzone) / (1.0 - c.deadzone);
                (1.0 - c.expo) * x + c.expo * x * x * x
            } else {
                0.0
            };
            g[k] = v.copysign(n);
        }
        let keep = |range: std::ops::Range<usize>, g: &mut [f64; 6], stats: &mut RateStats| {
            let best = range.clone().fold(None::<usize>, |b, i| match b {
                Some(j) if g[j].abs() >= g[i].abs() => Some(j),
                _ => Some(i),
            });
            for i in range {
                if Some(i) != best && g[i] != 0.0 {
                    g[i] = 0.0;
                    stats.suppressed_axes += 1;
                }
            }
        };
        match c.dominant {
            DominantAxis::Off => {}
            DominantAxis::Single => keep(0..6, &mut g, &mut stats),
            DominantAxis::PerGroup => {
                keep(0..3, &mut g, &mut stats);
                keep(3..6, &mut g, &mut stats);
            }
        }
        let twist = Twist {
            linear_m_s: Vector3::new(g[0], g[1], g[2]) * c.max_linear_speed_m_s,
            angular_rad_s: Vector3::new(g[3], g[4], g[5]) * c.max_angular_speed_rad_s,
        };
        (twist, stats)
    }

    /// Clutch and presence from the pressed buttons (bit i = button i). In
    /// [`PresenceMode::Toggle`] each new press of the operator button toggles presence.
    pub fn buttons(&mut self, pressed: u32) -> OperatorButtons {
        let c = &self.config;
        let bit = |b: u8| 1u32.checked_shl(u32::from(b)).unwrap_or(0);
        let op = bit(c.operator_button);
        let present = match c.presence {
            PresenceMode::Hold => pressed & op != 0,
            PresenceMode::Toggle => {
                if pressed & op != 0 && self.last_buttons & op == 0 {
                    self.toggled_present = !self.toggled_present;
                }
                self.toggled_present
            }
        };
        self.last_buttons = pressed;
        OperatorButtons {
            clutch: pressed & bit(c.clutch_button) != 0,
            operator_present: present,
        }
    }

    /// Forgets a toggled presence (device lost).
    pub fn release_all(&mut self) {
        self.toggled_present = false;
        self.last_buttons = 0;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    fn mapping(dominant: DominantAxis) -> RateMapping {
        RateMapping::new(RateMappingConfig {
            dominant,
            expo: 0.0,
            deadzone: 0.1,
            ..RateMappingConfig::spacemouse_evdev()
        })
        .unwrap()
    }

    /// Deadzone and the linear curve: 0 inside, continuous at its edge, full speed at full
    /// scale, signs per the map (device y → robot −y).
    #[test]
    fn deadzone_curve_and_signs() {
        let m = mapping(DominantAxis::Off);
        let t = |y: f64| {
            m.twist(&Deflection {
                axes: [0.0, y, 0.0, 0.0, 0.0, 0.0],
                buttons: 0,
            })
            .0
            .linear_m_s
            .y
        };
        assert_eq!(t(34.0), 0.0);
        assert_eq!(t(35.0), 0.0);
        assert!((t(350.0) + 0.010).abs() < 1e-15);
        assert!((t(-350.0) - 0.010).abs() < 1e-15);
        // half-way between deadzone and full scale: half speed (linear curve).
        assert!((t(-(35.0 + 157.5)) - 0.005).abs() < 1e-15);
        let (_, s) = m.twist(&Deflection {
            axes: [400.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            buttons: 0,
        });
        assert_eq!(s.saturated_axes, 1);
    }

    /// Dominant axis: only the strongest survives.
    #[test]
    fn dominant_axis() {
        let d = Deflection {
            axes: [200.0, 100.0, 0.0, 300.0, 0.0, 50.0],
            buttons: 0,
        };
        let (t, s) = mapping(DominantAxis::Single).twist(&d);
        assert_eq!(t.linear_m_s, Vector3::zeros());
        assert!(t.angular_rad_s.x > 0.0 && t.angular_rad_s.z == 0.0);
        assert_eq!(s.suppressed_axes, 3);
        let (t, _) = mapping(DominantAxis::PerGroup).twist(&d);
        assert!(t.linear_m_s.x > 0.0 && t.linear_m_s.y == 0.0);
    }

    #[test]
    fn buttons_and_toggle() {
        let mut m = mapping(DominantAxis::Off);
        assert_eq!(
            m.buttons(0b11),
            OperatorButtons {
                clutch: true,
                operator_present: true
            }
        );
        let mut t = RateMapping::new(RateMappingConfig {
            presence: PresenceMode::Toggle,
            ..RateMappingConfig::spacemouse_evdev()
        })
        .unwrap();
        assert!(t.buttons(0b10).operator_present);
        assert!(t.buttons(0b00).operator_present);
        assert!(!t.buttons(0b10).operator_present);
    }

    #[test]
    fn bad_configs_are_refused() {
        let mut c = RateMappingConfig::spacemouse_evdev();
        c.axis_map[1] = c.axis_map[0];
        assert!(matches!(
            RateMapping::new(c),
            Err(RateConfigError::AxisUsedTwice {
                first: 0,
                second: 1,
                ..
            })
        ));
        let c = RateMappingConfig {
            deadzone: 1.0,
            ..RateMappingConfig::spacemouse_evdev()
        };
        assert!(matches!(
            RateMapping::new(c),
            Err(RateConfigError::OutOfRange {
                field: "deadzone",
                ..
            })
        ));
    }
}
