//! Plant parameters: the TOML file `plant.toml`, its validation and its defaults.
//!
//! The structs mirror the file: every field is named after its TOML key and carries the
//! key's unit (`lead_mm`, `backlash_arcsec`, ...). [`crate::Plant::new`] converts to SI.
//! Per-joint overrides (`[joint.l2]`, `[joint.theta1]`, ...) are merged while parsing, so
//! [`PlantConfig`] holds one fully resolved parameter set per joint.

use std::fmt;

/// Names of the six joints, in joint order (`q = [l1, l2, l3, theta1, theta2, theta3]`).
pub const JOINT_NAMES: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// Why a configuration was rejected. Every variant names the offending key as a dotted
/// path (`prismatic.resistance_ohm`, `joint.l2.backlash_mm`, or `l2.backlash_mm` for a
/// config built in code).
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigError {
    /// The text is not valid TOML.
    Parse(String),
    /// A required key is absent.
    MissingKey(String),
    /// A key that the plant does not know (a typo, or a key of the other joint kind).
    UnknownKey(String),
    /// The key holds a value of the wrong TOML type.
    WrongType {
        /// Dotted key path.
        key: String,
        /// What was expected.
        expected: &'static str,
    },
    /// The value is not finite or lies outside the physical range accepted for the key.
    OutOfRange {
        /// Dotted key path.
        key: String,
        /// The rejected value.
        value: f64,
        /// Smallest accepted value.
        min: f64,
        /// Largest accepted value.
        max: f64,
    },
    /// Values that are each in range but contradict each other.
    Inconsistent {
        /// Dotted key path.
        key: String,
        /// What is wrong.
        message: String,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Parse(m) => write!(f, "plant config is not valid TOML: {m}"),
            ConfigError::MissingKey(k) => write!(f, "plant config: missing key `{k}`"),
            ConfigError::UnknownKey(k) => write!(f, "plant config: unknown key `{k}`"),
            ConfigError::WrongType { key, expected } => {
                write!(f, "plant config: `{key}` must be {expected}")
            }
            ConfigError::OutOfRange {
                key,
                value,
                min,
                max,
            } => write!(
                f,
                "plant config: `{key}` = {value} is not a finite value in [{min}, {max}]"
            ),
            ConfigError::Inconsistent { key, message } => {
                write!(f, "plant config: `{key}`: {message}")
            }
        }
    }
}

impl std::error::Error for ConfigError {}

fn check_range(key: &str, value: f64, min: f64, max: f64) -> Result<(), ConfigError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange {
            key: key.to_string(),
            value,
            min,
            max,
        })
    }
}

fn number(key: &str, value: &toml::Value) -> Result<f64, ConfigError> {
    match value {
        toml::Value::Float(x) => Ok(*x),
        // Integers are accepted for convenience (`supply_v = 24`); they are small here.
        toml::Value::Integer(i) => Ok(*i as f64),
        _ => Err(ConfigError::WrongType {
            key: key.to_string(),
            expected: "a number",
        }),
    }
}

/// Declares a struct of `f64` parameters, each with its accepted range, plus the lookup
/// table used by the parser and the validator. With a leading `common: Type;` the struct
/// also holds a part common to several tables (itself a `param_struct!`), whose keys the
/// table shares: one TOML table fills both, and errors name the key in that table.
macro_rules! param_struct {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$fmeta:meta])* $field:ident : [$min:expr, $max:expr] ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name {
            $( $(#[$fmeta])* pub $field: f64, )*
        }

        impl $name {
            /// Every key with its accepted range `(key, min, max)`.
            pub const KEYS: &'static [(&'static str, f64, f64)] =
                &[ $( (stringify!($field), $min, $max), )* ];

            fn set(&mut self, key: &str, value: f64) -> bool {
                match key {
                    $( stringify!($field) => { self.$field = value; true } )*
                    _ => false,
                }
            }

            fn get(&self, key: &str) -> Option<f64> {
                match key {
                    $( stringify!($field) => Some(self.$field), )*
                    _ => None,
                }
            }

            /// Checks every value against its range; `prefix` names the table in errors.
            pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
                for (key, min, max) in Self::KEYS {
                    let value = self.get(key).unwrap_or(f64::NAN);
                    check_range(&format!("{prefix}.{key}"), value, *min, *max)?;
                }
                self.check_consistency(prefix)
            }

            /// Reads the keys of one TOML table into `self`; every key must be known.
            /// Returns the keys that were present.
            fn read_table(
                &mut self,
                prefix: &str,
                table: &toml::Table,
            ) -> Result<Vec<&'static str>, ConfigError> {
                let mut seen = Vec::new();
                for (key, value) in table {
                    let path = format!("{prefix}.{key}");
                    let Some((name, min, max)) =
                        Self::KEYS.iter().find(|(k, _, _)| *k == key.as_str())
                    else {
                        return Err(ConfigError::UnknownKey(path));
                    };
                    let x = number(&path, value)?;
                    check_range(&path, x, *min, *max)?;
                    self.set(name, x);
                    seen.push(*name);
                }
                Ok(seen)
            }

            /// Every value NaN (before a table is read).
            #[allow(dead_code)]
            fn unset() -> Self {
                Self { $( $field: f64::NAN, )* }
            }

            #[allow(dead_code)]
            fn from_table(prefix: &str, table: &toml::Table) -> Result<Self, ConfigError> {
                let mut out = Self { $( $field: f64::NAN, )* };
                let seen = out.read_table(prefix, table)?;
                for (key, _, _) in Self::KEYS {
                    if !seen.contains(key) {
                        return Err(ConfigError::MissingKey(format!("{prefix}.{key}")));
                    }
                }
                Ok(out)
            }
        }
    };
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(#[$cmeta:meta])* $common:ident : $ctype:ty;
            $( $(#[$fmeta:meta])* $field:ident : [$min:expr, $max:expr] ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name {
            $(#[$cmeta])* pub $common: $ctype,
            $( $(#[$fmeta])* pub $field: f64, )*
        }

        impl $name {
            /// The keys of this table's own part with their accepted ranges
            /// `(key, min, max)` (the common part's are its own `KEYS`).
            pub const KEYS: &'static [(&'static str, f64, f64)] =
                &[ $( (stringify!($field), $min, $max), )* ];

            fn set(&mut self, key: &str, value: f64) -> bool {
                match key {
                    $( stringify!($field) => { self.$field = value; true } )*
                    _ => self.$common.set(key, value),
                }
            }

            fn get(&self, key: &str) -> Option<f64> {
                match key {
                    $( stringify!($field) => Some(self.$field), )*
                    _ => self.$common.get(key),
                }
            }

            /// Every key of the table, the common part's first, with its range.
            fn all_keys() -> impl Iterator<Item = &'static (&'static str, f64, f64)> {
                <$ctype>::KEYS.iter().chain(Self::KEYS.iter())
            }

            /// Checks every value against its range; `prefix` names the table in errors.
            pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
                for (key, min, max) in Self::all_keys() {
                    let value = self.get(key).unwrap_or(f64::NAN);
                    check_range(&format!("{prefix}.{key}"), value, *min, *max)?;
                }
                self.check_consistency(prefix)
            }

            /// Reads the keys of one TOML table into `self`; every key must be known.
            /// Returns the keys that were present.
            fn read_table(
                &mut self,
                prefix: &str,
                table: &toml::Table,
            ) -> Result<Vec<&'static str>, ConfigError> {
                let mut seen = Vec::new();
                for (key, value) in table {
                    let path = format!("{prefix}.{key}");
                    let Some((name, min, max)) =
                        Self::all_keys().find(|(k, _, _)| *k == key.as_str())
                    else {
                        return Err(ConfigError::UnknownKey(path));
                    };
                    let x = number(&path, value)?;
                    check_range(&path, x, *min, *max)?;
                    self.set(name, x);
                    seen.push(*name);
                }
                Ok(seen)
            }

            fn from_table(prefix: &str, table: &toml::Table) -> Result<Self, ConfigError> {
                let mut out = Self {
                    $common: <$ctype>::unset(),
                    $( $field: f64::NAN, )*
                };
                let seen = out.read_table(prefix, table)?;
                for (key, _, _) in Self::all_keys() {
                    if !seen.contains(key) {
                        return Err(ConfigError::MissingKey(format!("{prefix}.{key}")));
                    }
                }
                Ok(out)
            }
        }
    };
}

param_struct! {
    /// The H-bridges (all six share the supply).
    pub struct HBridgeConfig {
        /// Supply voltage, V. Duty 1 applies this to the motor.
        supply_v: [1.0, 100.0],
        /// Resistance of the conducting switches in series with the motor, ohm.
        on_resistance_ohm: [0.0, 10.0],
    }
}

param_struct! {
    /// The spring-applied holding brakes on the motor shafts (all six alike in timing).
    pub struct BrakeConfig {
        /// Time from the coil's power removed to the brake holding, ms.
        engage_ms: [0.0, 1000.0],
        /// Time from the coil powered to the brake free, ms.
        release_ms: [0.0, 1000.0],
    }
}

param_struct! {
    /// What both kinds of joint have alike, in the units of their names: the DC motor, its
    /// driver (current regulation, overcurrent protection), the brake on its shaft, the
    /// friction at the motor shaft, and the gearing's efficiency and inertia at the motor.
    /// In the file these keys sit in `[prismatic]` and `[rotary]` beside the kind's own.
    pub struct DriveConfig {
        /// Motor terminal resistance, ohm.
        resistance_ohm: [0.01, 1000.0],
        /// Motor terminal inductance, H.
        inductance_h: [1e-7, 0.1],
        /// Torque constant Kt, N m/A.
        torque_constant_nm_per_a: [1e-4, 2.0],
        /// Back-EMF constant Ke, V s/rad (equal to Kt in SI for a DC motor).
        back_emf_v_s_per_rad: [1e-4, 2.0],
        /// Rotor inertia, kg m^2.
        rotor_inertia_kg_m2: [1e-10, 1e-2],
        /// Maximum continuous (thermal) current, A.
        nominal_current_a: [1e-3, 200.0],
        /// The driver's current regulation (cycle-by-cycle chopping): the largest
        /// |current| the H-bridge lets flow, A.
        current_limit_a: [1e-3, 1000.0],
        /// The driver's overcurrent protection (drain-source voltage monitoring of its
        /// transistors, independent of the regulation): above this |current| it latches its
        /// fault and turns the bridge off, A.
        driver_ocp_a: [1e-3, 1000.0],
        /// Holding torque of the spring-applied brake on the motor shaft, N m (0: none).
        brake_holding_torque_nm: [0.0, 10.0],
        /// Coulomb friction torque at the motor shaft (motor + transmission drag), N m.
        coulomb_friction_motor_side_nm: [0.0, 1.0],
        /// Viscous friction at the motor shaft, N m s/rad.
        viscous_friction_motor_side_nm_s_per_rad: [0.0, 0.1],
        /// Static (breakaway) over Coulomb friction, for the motor and the load side.
        breakaway_to_coulomb_ratio: [1.0, 5.0],
        /// Efficiency of the gearing when driving the load, 0..1 (the lead screw's own
        /// is apart).
        gear_efficiency: [0.05, 1.0],
        /// Inertia of the transmission (gears, and a screw) referred to the motor shaft,
        /// kg m^2.
        transmission_inertia_kg_m2: [0.0, 1e-2],
    }
}

param_struct! {
    /// Parameters of one prismatic (lead-screw) joint, in the units of their names.
    pub struct PrismaticConfig {
        /// The motor, its driver and brake, the motor-side friction and gearing.
        drive: DriveConfig;
        /// Gear reduction between motor and lead screw (motor revolutions per screw
        /// revolution).
        gear_ratio: [0.05, 1000.0],
        /// Lead of the screw (travel per screw revolution), mm.
        lead_mm: [0.05, 100.0],
        /// Efficiency of the lead screw when driving the load, 0..1.
        leadscrew_efficiency: [0.05, 1.0],
        /// Total backlash between motor and load, along the joint, mm.
        backlash_mm: [0.0, 5.0],
        /// Moving mass on the load side of the backlash, kg.
        load_mass_kg: [1e-3, 100.0],
        /// Coulomb friction on the load side, N.
        load_coulomb_friction_n: [0.0, 1000.0],
        /// Viscous friction on the load side, N s/m.
        load_viscous_friction_n_s_per_m: [0.0, 1e5],
    }
}

param_struct! {
    /// Parameters of one rotary (rotating-link) joint, in the units of their names.
    pub struct RotaryConfig {
        /// The motor, its driver and brake, the motor-side friction and gearing.
        drive: DriveConfig;
        /// Overall reduction, motor revolutions per link revolution.
        gear_ratio: [1.0, 10000.0],
        /// Total backlash between motor and link, at the link, arc-seconds.
        backlash_arcsec: [0.0, 36000.0],
        /// Inertia of the link and what it carries, about its axis, kg m^2.
        load_inertia_kg_m2: [1e-7, 10.0],
        /// Coulomb friction on the load side, N m.
        load_coulomb_friction_nm: [0.0, 100.0],
        /// Viscous friction on the load side, N m s/rad.
        load_viscous_friction_nm_s_per_rad: [0.0, 1e3],
    }
}

param_struct! {
    /// The second position channel: an absolute position sensor per joint on the load side
    /// (potentiometers read by a 16-bit converter on the board; `crate::position_sensor`).
    pub struct PositionSensorConfig {
        /// Electrical travel of a leg's linear potentiometer (65536 counts), mm.
        leg_travel_mm: [1.0, 1000.0],
        /// The leg length at the potentiometer's mid-travel, mm.
        leg_mid_mm: [0.0, 1000.0],
        /// Electrical angle of a link's single-turn potentiometer (65536 counts), deg.
        link_travel_deg: [1.0, 360.0],
        /// The link angle at the potentiometer's mid-angle, deg.
        link_mid_deg: [-180.0, 180.0],
        /// Noise of a reading, counts rms.
        noise_lsb: [0.0, 1000.0],
        /// The residual offset the channel's calibration leaves, counts (the same on every
        /// joint).
        offset_lsb: [-1000.0, 1000.0],
    }
}

/// Kt and Ke of one motor must agree (they are the same constant in SI units).
fn check_kt_ke(prefix: &str, kt: f64, ke: f64) -> Result<(), ConfigError> {
    let rel = (kt - ke).abs() / kt.max(ke);
    if rel > 0.1 {
        return Err(ConfigError::Inconsistent {
            key: format!("{prefix}.back_emf_v_s_per_rad"),
            message: format!(
                "back-EMF constant {ke} V s/rad differs from the torque constant {kt} N m/A \
                 by more than 10 % (they are equal in SI units)"
            ),
        });
    }
    Ok(())
}

impl HBridgeConfig {
    fn check_consistency(&self, _prefix: &str) -> Result<(), ConfigError> {
        Ok(())
    }
}

impl PositionSensorConfig {
    fn check_consistency(&self, _prefix: &str) -> Result<(), ConfigError> {
        Ok(())
    }

    /// Converter counts per metre of a leg.
    pub fn leg_counts_per_m(&self) -> f64 {
        65536.0 / (self.leg_travel_mm * 1e-3)
    }

    /// Converter counts per radian of a link.
    pub fn link_counts_per_rad(&self) -> f64 {
        65536.0 / self.link_travel_deg.to_radians()
    }
}

impl BrakeConfig {
    fn check_consistency(&self, _prefix: &str) -> Result<(), ConfigError> {
        Ok(())
    }
}

impl DriveConfig {
    fn check_consistency(&self, prefix: &str) -> Result<(), ConfigError> {
        check_kt_ke(
            prefix,
            self.torque_constant_nm_per_a,
            self.back_emf_v_s_per_rad,
        )
    }
}

impl PrismaticConfig {
    fn check_consistency(&self, prefix: &str) -> Result<(), ConfigError> {
        self.drive.check_consistency(prefix)
    }
}

impl RotaryConfig {
    fn check_consistency(&self, prefix: &str) -> Result<(), ConfigError> {
        self.drive.check_consistency(prefix)
    }
}

/// The quadrature encoders on the motor shafts (all six alike).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderConfig {
    /// Lines (slots) per motor revolution.
    pub lines_per_rev: u32,
    /// Edges counted per line: 1, 2 or 4 (x4 = both edges of both channels).
    pub quadrature_factor: u32,
}

impl EncoderConfig {
    /// Counts per motor revolution.
    pub fn counts_per_rev(&self) -> u32 {
        self.lines_per_rev * self.quadrature_factor
    }

    /// Checks the two integers.
    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        check_range(
            &format!("{prefix}.lines_per_rev"),
            f64::from(self.lines_per_rev),
            1.0,
            100_000.0,
        )?;
        if !matches!(self.quadrature_factor, 1 | 2 | 4) {
            return Err(ConfigError::Inconsistent {
                key: format!("{prefix}.quadrature_factor"),
                message: format!("must be 1, 2 or 4, not {}", self.quadrature_factor),
            });
        }
        Ok(())
    }

    fn from_table(prefix: &str, table: &toml::Table) -> Result<Self, ConfigError> {
        let mut lines = None;
        let mut quad = None;
        for (key, value) in table {
            let path = format!("{prefix}.{key}");
            let slot = match key.as_str() {
                "lines_per_rev" => &mut lines,
                "quadrature_factor" => &mut quad,
                _ => return Err(ConfigError::UnknownKey(path)),
            };
            let toml::Value::Integer(i) = value else {
                return Err(ConfigError::WrongType {
                    key: path,
                    expected: "an integer",
                });
            };
            let v = u32::try_from(*i).map_err(|_| ConfigError::OutOfRange {
                key: path.clone(),
                value: *i as f64,
                min: 1.0,
                max: 100_000.0,
            })?;
            *slot = Some(v);
        }
        let cfg = EncoderConfig {
            lines_per_rev: lines
                .ok_or_else(|| ConfigError::MissingKey(format!("{prefix}.lines_per_rev")))?,
            quadrature_factor: quad
                .ok_or_else(|| ConfigError::MissingKey(format!("{prefix}.quadrature_factor")))?,
        };
        cfg.validate(prefix)?;
        Ok(cfg)
    }
}

/// The whole plant: H-bridges, encoders and the six joints (overrides already merged).
#[derive(Debug, Clone, PartialEq)]
pub struct PlantConfig {
    /// `[hbridge]`.
    pub hbridge: HBridgeConfig,
    /// `[brake]`.
    pub brake: BrakeConfig,
    /// `[encoder]`.
    pub encoder: EncoderConfig,
    /// `[position_sensor]`.
    pub position_sensor: PositionSensorConfig,
    /// `[prismatic]` merged with `[joint.l1]` .. `[joint.l3]`: joints l1, l2, l3.
    pub prismatic: [PrismaticConfig; 3],
    /// `[rotary]` merged with `[joint.theta1]` .. `[joint.theta3]`: joints theta1..theta3.
    pub rotary: [RotaryConfig; 3],
}

/// The shipped parameter file, `sim/plant/plant.toml`.
pub const SHIPPED_TOML: &str = include_str!("../plant.toml");

fn sub_table<'a>(root: &'a toml::Table, key: &str) -> Result<Option<&'a toml::Table>, ConfigError> {
    match root.get(key) {
        None => Ok(None),
        Some(toml::Value::Table(t)) => Ok(Some(t)),
        Some(_) => Err(ConfigError::WrongType {
            key: key.to_string(),
            expected: "a table",
        }),
    }
}

fn required_table<'a>(root: &'a toml::Table, key: &str) -> Result<&'a toml::Table, ConfigError> {
    sub_table(root, key)?.ok_or_else(|| ConfigError::MissingKey(format!("[{key}]")))
}

impl PlantConfig {
    /// Parses and validates a plant parameter file (the format of `plant.toml`).
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let root: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| ConfigError::Parse(e.to_string()))?;
        for key in root.keys() {
            if !matches!(
                key.as_str(),
                "hbridge"
                    | "brake"
                    | "encoder"
                    | "position_sensor"
                    | "prismatic"
                    | "rotary"
                    | "joint"
            ) {
                return Err(ConfigError::UnknownKey(key.clone()));
            }
        }
        let hbridge = HBridgeConfig::from_table("hbridge", required_table(&root, "hbridge")?)?;
        let brake = BrakeConfig::from_table("brake", required_table(&root, "brake")?)?;
        let encoder = EncoderConfig::from_table("encoder", required_table(&root, "encoder")?)?;
        let position_sensor = PositionSensorConfig::from_table(
            "position_sensor",
            required_table(&root, "position_sensor")?,
        )?;
        let prismatic =
            PrismaticConfig::from_table("prismatic", required_table(&root, "prismatic")?)?;
        let rotary = RotaryConfig::from_table("rotary", required_table(&root, "rotary")?)?;
        // Whole sections first, so that errors name the section the value came from.
        hbridge.validate("hbridge")?;
        brake.validate("brake")?;
        position_sensor.validate("position_sensor")?;
        prismatic.validate("prismatic")?;
        rotary.validate("rotary")?;
        let mut cfg = PlantConfig {
            hbridge,
            brake,
            encoder,
            position_sensor,
            prismatic: [prismatic; 3],
            rotary: [rotary; 3],
        };
        if let Some(joints) = sub_table(&root, "joint")? {
            for (name, value) in joints {
                let prefix = format!("joint.{name}");
                let toml::Value::Table(t) = value else {
                    return Err(ConfigError::WrongType {
                        key: prefix,
                        expected: "a table",
                    });
                };
                match JOINT_NAMES.iter().position(|n| *n == name.as_str()) {
                    Some(j) if j < 3 => {
                        cfg.prismatic[j].read_table(&prefix, t)?;
                    }
                    Some(j) => {
                        cfg.rotary[j - 3].read_table(&prefix, t)?;
                    }
                    None => return Err(ConfigError::UnknownKey(prefix)),
                }
            }
        }
        cfg.validate()?;
        Ok(cfg)
    }

    /// Parses the shipped `plant.toml` (embedded at compile time).
    pub fn shipped() -> Result<Self, ConfigError> {
        Self::from_toml_str(SHIPPED_TOML)
    }

    /// Checks every value (finite, in its physical range, Kt = Ke). Errors name the key as
    /// `hbridge.supply_v`, `l2.backlash_mm`, `theta1.gear_ratio`, ...
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.hbridge.validate("hbridge")?;
        self.brake.validate("brake")?;
        self.encoder.validate("encoder")?;
        self.position_sensor.validate("position_sensor")?;
        for (j, p) in self.prismatic.iter().enumerate() {
            p.validate(JOINT_NAMES[j])?;
        }
        for (j, r) in self.rotary.iter().enumerate() {
            r.validate(JOINT_NAMES[j + 3])?;
        }
        Ok(())
    }
}

impl Default for PlantConfig {
    /// The values of the shipped `plant.toml` (a test checks that the two agree).
    fn default() -> Self {
        let prismatic = PrismaticConfig {
            drive: DriveConfig {
                resistance_ohm: 0.317,
                inductance_h: 0.0823e-3,
                torque_constant_nm_per_a: 0.0302,
                back_emf_v_s_per_rad: 0.0302,
                rotor_inertia_kg_m2: 142e-7,
                nominal_current_a: 5.77,
                current_limit_a: 5.23,
                driver_ocp_a: 15.0,
                brake_holding_torque_nm: 0.1,
                coulomb_friction_motor_side_nm: 5.1e-3,
                viscous_friction_motor_side_nm_s_per_rad: 1.0e-6,
                breakaway_to_coulomb_ratio: 1.2,
                gear_efficiency: 0.95,
                transmission_inertia_kg_m2: 3.0e-7,
            },
            gear_ratio: 2.0,
            lead_mm: 6.0,
            leadscrew_efficiency: 0.70,
            backlash_mm: 0.12,
            load_mass_kg: 0.4,
            load_coulomb_friction_n: 2.0,
            load_viscous_friction_n_s_per_m: 5.0,
        };
        let rotary = RotaryConfig {
            drive: DriveConfig {
                resistance_ohm: 2.14,
                inductance_h: 0.238e-3,
                torque_constant_nm_per_a: 0.0234,
                back_emf_v_s_per_rad: 0.0234,
                rotor_inertia_kg_m2: 10.8e-7,
                nominal_current_a: 1.2,
                current_limit_a: 0.66,
                driver_ocp_a: 2.0,
                brake_holding_torque_nm: 0.03,
                coulomb_friction_motor_side_nm: 0.9e-3,
                viscous_friction_motor_side_nm_s_per_rad: 1.0e-7,
                breakaway_to_coulomb_ratio: 1.2,
                gear_efficiency: 0.90,
                transmission_inertia_kg_m2: 0.5e-7,
            },
            gear_ratio: 36.0,
            backlash_arcsec: 20.0,
            load_inertia_kg_m2: 3.5e-3,
            load_coulomb_friction_nm: 0.01,
            load_viscous_friction_nm_s_per_rad: 1.0e-3,
        };
        PlantConfig {
            hbridge: HBridgeConfig {
                supply_v: 24.0,
                on_resistance_ohm: 0.03,
            },
            brake: BrakeConfig {
                engage_ms: 15.0,
                release_ms: 25.0,
            },
            encoder: EncoderConfig {
                lines_per_rev: 500,
                quadrature_factor: 4,
            },
            position_sensor: PositionSensorConfig {
                leg_travel_mm: 100.0,
                leg_mid_mm: 177.0,
                link_travel_deg: 340.0,
                link_mid_deg: 0.0,
                noise_lsb: 1.0,
                offset_lsb: 2.0,
            },
            prismatic: [prismatic; 3],
            rotary: [rotary; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_equals_the_shipped_file() -> Result<(), ConfigError> {
        assert_eq!(PlantConfig::shipped()?, PlantConfig::default());
        Ok(())
    }

    #[test]
    fn every_key_of_a_section_is_required() {
        let text = SHIPPED_TOML.replace("lead_mm = 6.0", "");
        assert_eq!(
            PlantConfig::from_toml_str(&text),
            Err(ConfigError::MissingKey("prismatic.lead_mm".into()))
        );
    }
}
