//! The board profile: the one owner of the facts about the board and the drive trains it
//! controls. The control period (the board's timer, the controller's rate, the watchdog's
//! schedule), the CPU clock, each joint's encoder, gearing and lead, and each joint's
//! mechanical range are written here and nowhere else; the board image, the simulated
//! board, the emulated board, the on-target tests, the fuzz harness and the calibration
//! build from it, and the plant model is tested equal to it.
//!
//! [`BoardProfile::REFERENCE`] is the RSPR prototype's board; its TOML form is
//! `firmware/profile/reference.toml` (read with the `toml` feature on the host; a test
//! checks the two are the same profile).
#![cfg_attr(not(feature = "std"), no_std)]

pub mod position_channel;

/// The number of joints, in the order `l1, l2, l3, theta1, theta2, theta3`.
pub const NUM_JOINTS: usize = 6;

/// What kind of joint a drive train moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "toml", derive(serde::Deserialize))]
#[cfg_attr(feature = "toml", serde(rename_all = "lowercase"))]
pub enum JointKind {
    /// A leg: a lead screw; positions in m.
    Prismatic,
    /// A rotating link; positions in rad.
    Revolute,
}

/// One joint's drive train and encoder.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "toml", derive(serde::Deserialize))]
#[cfg_attr(feature = "toml", serde(deny_unknown_fields))]
pub struct JointProfile {
    /// A leg or a link.
    pub kind: JointKind,
    /// The motor encoder's lines per revolution.
    pub encoder_lines_per_rev: u32,
    /// Edges counted per line (4: both edges of both channels).
    pub quadrature: u32,
    /// Motor revolutions per revolution of the lead screw (a leg) or of the link.
    pub gear_ratio: f64,
    /// The lead screw's lead, m per screw revolution (0 for a link).
    pub lead_m: f64,
    /// The mechanical range, m or rad: a measured joint beyond it is a fault.
    pub range: [f64; 2],
}

impl JointProfile {
    /// Encoder counts per motor revolution.
    pub const fn counts_per_rev(&self) -> u32 {
        self.encoder_lines_per_rev * self.quadrature
    }

    /// Encoder counts per joint unit: per metre of a leg (the counts of a motor revolution
    /// over the travel of one, `lead / gear`), per radian of a link (over the degrees of
    /// one, `360 / gear`).
    pub fn counts_per_unit(&self) -> f64 {
        let per_rev = f64::from(self.counts_per_rev());
        match self.kind {
            JointKind::Prismatic => per_rev / (self.lead_m / self.gear_ratio),
            JointKind::Revolute => {
                per_rev / ((360.0 / self.gear_ratio) * core::f64::consts::PI / 180.0)
            }
        }
    }

    /// The joint's travel per encoder count, m or rad.
    pub fn unit_per_count(&self) -> f64 {
        1.0 / self.counts_per_unit()
    }
}

/// The board profile.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "toml", derive(serde::Deserialize))]
#[cfg_attr(feature = "toml", serde(deny_unknown_fields))]
pub struct BoardProfile {
    /// The control period, µs.
    pub control_period_us: u32,
    /// The CPU's core clock, Hz.
    pub cpu_hz: u32,
    /// The joints, in order.
    pub joints: [JointProfile; NUM_JOINTS],
}

const fn leg() -> JointProfile {
    JointProfile {
        kind: JointKind::Prismatic,
        encoder_lines_per_rev: 500,
        quadrature: 4,
        gear_ratio: 2.0,
        lead_m: 0.006,
        range: [0.142, 0.212],
    }
}

/// 83 deg in rad (the links' range: 3 deg beyond the guards' 80 deg).
const LINK_LIMIT_RAD: f64 = 1.448_623_279_155_293_5;

const fn link() -> JointProfile {
    JointProfile {
        kind: JointKind::Revolute,
        encoder_lines_per_rev: 500,
        quadrature: 4,
        gear_ratio: 36.0,
        lead_m: 0.0,
        range: [-LINK_LIMIT_RAD, LINK_LIMIT_RAD],
    }
}

/// Why a profile is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProfileError {
    /// The control period is outside 100 .. 10 000 µs.
    Period(u32),
    /// The core clock is 0.
    Clock,
    /// A joint's encoder, gearing, lead or range makes no sense (the joint).
    Joint(usize),
    /// A joint's kind is not the robot's (legs first, then links; the joint).
    Kind(usize),
}

impl core::fmt::Display for ProfileError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ProfileError::Period(p) => {
                write!(f, "control_period_us {p} is outside 100 .. 10000 us")
            }
            ProfileError::Clock => f.write_str("cpu_hz must be positive"),
            ProfileError::Joint(j) => write!(
                f,
                "joint {j}: encoder lines, quadrature, gear ratio and (for a leg) lead must be \
                 positive and the range increasing"
            ),
            ProfileError::Kind(j) => {
                write!(f, "joint {j}: l1..l3 are prismatic, theta1..3 revolute")
            }
        }
    }
}

impl BoardProfile {
    /// The RSPR prototype's board (STM32F405RG at 168 MHz, a 1 kHz control period; the
    /// drive trains of thesis T11.2).
    pub const REFERENCE: BoardProfile = BoardProfile {
        control_period_us: 1000,
        cpu_hz: 168_000_000,
        joints: [leg(), leg(), leg(), link(), link(), link()],
    };

    /// The control period, s.
    pub fn period_s(&self) -> f64 {
        f64::from(self.control_period_us) * 1e-6
    }

    /// The control rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        1e6 / f64::from(self.control_period_us)
    }

    /// Every joint's encoder counts per unit (m, rad).
    pub fn counts_per_unit(&self) -> [f64; NUM_JOINTS] {
        self.joints.map(|j| j.counts_per_unit())
    }

    /// Every joint's mechanical range.
    pub fn ranges(&self) -> [[f64; 2]; NUM_JOINTS] {
        self.joints.map(|j| j.range)
    }

    /// Checks the profile.
    pub fn validate(&self) -> Result<(), ProfileError> {
        if !(100..=10_000).contains(&self.control_period_us) {
            return Err(ProfileError::Period(self.control_period_us));
        }
        if self.cpu_hz == 0 {
            return Err(ProfileError::Clock);
        }
        for (i, j) in self.joints.iter().enumerate() {
            let leg = i < NUM_JOINTS / 2;
            let kind_ok = (j.kind == JointKind::Prismatic) == leg;
            if !kind_ok {
                return Err(ProfileError::Kind(i));
            }
            let ok = j.encoder_lines_per_rev > 0
                && j.quadrature > 0
                && j.gear_ratio.is_finite()
                && j.gear_ratio > 0.0
                && (!leg || (j.lead_m.is_finite() && j.lead_m > 0.0))
                && j.range[0].is_finite()
                && j.range[1].is_finite()
                && j.range[0] < j.range[1];
            if !ok {
                return Err(ProfileError::Joint(i));
            }
        }
        Ok(())
    }
}

/// The TOML form.
#[cfg(feature = "toml")]
pub mod file {
    use super::{BoardProfile, ProfileError};

    /// Why a profile file cannot be read.
    #[derive(Debug)]
    pub enum FileError {
        /// Not TOML, or not a profile (the parser's message names the key).
        Parse(String),
        /// A value out of its range.
        Invalid(ProfileError),
    }

    impl core::fmt::Display for FileError {
        fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
            match self {
                FileError::Parse(e) => write!(f, "board profile: {e}"),
                FileError::Invalid(e) => write!(f, "board profile: {e}"),
            }
        }
    }

    impl std::error::Error for FileError {}

    impl BoardProfile {
        /// A profile from its TOML form, checked.
        pub fn from_toml_str(text: &str) -> Result<Self, FileError> {
            let p: BoardProfile =
                toml::from_str(text).map_err(|e| FileError::Parse(e.to_string()))?;
            p.validate().map_err(FileError::Invalid)?;
            Ok(p)
        }
    }
}
