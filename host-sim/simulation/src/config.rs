//! The simulation settings: `host-sim/simulation/default.toml` (embedded) overlaid with
//! the keys of a `--config FILE` ([`robot_config::overlay()`]), then validated.
//!
//! The embedded file is the schema: a key that it does not have is unknown, and a value
//! must have the type of the default it replaces (an integer may stand for a float); the
//! arrays keep their default's length except the pass lists and the list of steps. Every
//! error names the key by its dotted path (`control.rate_hz`, `scenario.step.hold_s`).

use robot_config::overlay::{overlay, OverlayError};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use thiserror::Error;
use trajectory::{Laparoscope, MasterLimits};

/// The embedded default settings (also the schema of a `--config` file).
pub const DEFAULT_TOML: &str = include_str!("../default.toml");

/// The arrays of the settings whose length may differ from their default's.
const VARIABLE_LENGTH: [&str; 3] = [
    "scenario.laparoscope.pass_speeds_mm_s",
    "scenario.laparoscope.pass_scales",
    "scenario.step.steps_mm_deg",
];

/// Settings that cannot be used; every message names the key.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The embedded defaults or the given text is not TOML (`what` says which).
    #[error("{what} is not valid TOML: {source}")]
    NotToml {
        what: &'static str,
        source: toml::de::Error,
    },
    /// An unknown key, a value of the wrong type or length.
    #[error(transparent)]
    Overlay(#[from] OverlayError),
    /// The overlaid settings do not fit their layout.
    #[error("configuration: {message}")]
    Layout { message: String },
    /// A value outside its range.
    #[error("`{key}` must be within {low} .. {high}, got {value}")]
    OutOfRange {
        key: String,
        low: f64,
        high: f64,
        value: f64,
    },
    /// A value that must be finite and positive.
    #[error("`{key}` must be finite and > 0, got {value}")]
    NotPositive { key: String, value: f64 },
    #[error(
        "`control.plant_steps_per_tick` must be within 10 .. 1000 (the plant runs at least \
         10x the control rate), got {0}"
    )]
    PlantSteps(u32),
    #[error("`plant.payload_update` must be \"moved\", \"tick\" or \"step\", got {0:?}")]
    PayloadUpdate(String),
    #[error("`output.trace_every_ticks` must be at least 1")]
    TraceEvery,
    #[error("`scenario.laparoscope.pass_speeds_mm_s` needs at least one pass")]
    NoPass,
    #[error(
        "`scenario.laparoscope.pass_scales` must have one entry per pass speed ({speeds}), \
         got {scales}"
    )]
    PassScales { speeds: usize, scales: usize },
    #[error("`scenario.step.steps_mm_deg` needs at least one step")]
    NoStep,
    #[error("cannot read the config {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config {}: {error}", path.display())]
    InFile {
        path: PathBuf,
        error: Box<ConfigError>,
    },
}

/// Everything `host-sim sim` reads from its configuration.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    pub control: ControlSection,
    pub plant: PlantSection,
    pub payload: PayloadSection,
    pub master: MasterSection,
    pub output: OutputSection,
    pub accuracy: AccuracySection,
    pub scenario: ScenarioSections,
}

/// `[control]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ControlSection {
    pub rate_hz: f64,
    pub plant_steps_per_tick: u32,
    pub backlash_compensation: bool,
    pub compensated_leg_backlash_mm: f64,
}

/// Where the payload wrench is mapped to the joints, tau = J^-T s_e at the true pose
/// (`plant.payload_update`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PayloadUpdate {
    /// Once per control tick.
    Tick,
    /// Every plant step.
    Step,
    /// At a control tick where the true pose has moved more than `plant.payload_refresh_mm`
    /// (o_p) or `plant.payload_refresh_deg` since the last mapping (and when the tool is
    /// attached). The loads between two mappings are off by at most the change of tau over
    /// that motion, which the thresholds bound (see `host-sim/simulation/default.toml`).
    Moved,
}

/// `[plant]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlantSection {
    pub config_file: String,
    pub leg_backlash_mm: f64,
    /// "moved", "tick" or "step" (see [`PlantSection::payload_update`]).
    pub payload_update: String,
    /// The motion of o_p, mm, and the rotation, deg, after which "moved" maps again.
    pub payload_refresh_mm: f64,
    pub payload_refresh_deg: f64,
}

impl PlantSection {
    /// `payload_update` (validated by [`SimConfig::validate`]; anything but "step" and
    /// "moved" is "tick").
    pub fn payload_update(&self) -> PayloadUpdate {
        match self.payload_update.as_str() {
            "step" => PayloadUpdate::Step,
            "moved" => PayloadUpdate::Moved,
            _ => PayloadUpdate::Tick,
        }
    }
}

/// `[payload]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PayloadSection {
    pub enabled: bool,
    pub mass_kg: f64,
    pub gravity_m_s2: f64,
    pub lever_mm: [f64; 3],
}

/// `[master]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MasterSection {
    pub stream_rate_hz: f64,
    pub latency_ms: f64,
    pub accel_mm_s2: f64,
    pub angular_speed_deg_s: f64,
    pub angular_accel_deg_s2: f64,
}

impl MasterSection {
    /// The master's limits on a straight move.
    pub fn limits(&self) -> MasterLimits {
        MasterLimits {
            accel_mm_s2: self.accel_mm_s2,
            angular_speed_deg_s: self.angular_speed_deg_s,
            angular_accel_deg_s2: self.angular_accel_deg_s2,
        }
    }
}

/// `[output]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    pub dir: String,
    pub trace_every_ticks: u32,
    pub plots: bool,
}

/// `[accuracy]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AccuracySection {
    pub tip_rms_mm: f64,
    pub tip_max_mm: f64,
    pub judged_speed_mm_s: f64,
}

/// `[scenario.*]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSections {
    pub laparoscope: Laparoscope,
    pub step: StepSection,
    pub box_sweep: BoxSweepSection,
    pub payload: PayloadScenarioSection,
    pub backlash_off: BacklashOffSection,
}

/// `[scenario.step]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StepSection {
    pub steps_mm_deg: Vec<[f64; 6]>,
    pub hold_s: f64,
    pub settle_band_mm: f64,
    pub settle_band_deg: f64,
}

/// `[scenario.box_sweep]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoxSweepSection {
    pub speed_mm_s: f64,
    pub tilt_deg: f64,
    pub hold_s: f64,
    pub reach: f64,
    pub tail_s: f64,
}

/// `[scenario.payload]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PayloadScenarioSection {
    pub attach_s: f64,
    pub hold_s: f64,
    pub speed_mm_s: f64,
    pub move_to_mm_deg: [f64; 6],
}

/// `[scenario.backlash_off]` (no keys).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BacklashOffSection {}

fn parse_table(text: &str, what: &'static str) -> Result<toml::Table, ConfigError> {
    text.parse::<toml::Table>()
        .map_err(|source| ConfigError::NotToml { what, source })
}

impl SimConfig {
    /// The embedded defaults (`host-sim/simulation/default.toml`).
    pub fn builtin() -> Result<Self, ConfigError> {
        Self::from_toml_str("")
    }

    /// The defaults overlaid with the keys of `text` (a `--config` file), validated.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let mut base = parse_table(DEFAULT_TOML, "the embedded default.toml")?;
        // The control rate defaults to the board's (the board profile owns it).
        if let Some(toml::Value::Table(control)) = base.get_mut("control") {
            control.insert(
                "rate_hz".to_string(),
                toml::Value::Float(board_profile::BoardProfile::REFERENCE.rate_hz()),
            );
        }
        let user = parse_table(text, "the configuration")?;
        overlay(&mut base, user, &VARIABLE_LENGTH)?;
        let cfg: SimConfig =
            toml::Value::Table(base)
                .try_into()
                .map_err(|e: toml::de::Error| ConfigError::Layout {
                    message: e.message().to_string(),
                })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads `path` (or the defaults when `None`).
    pub fn load(path: Option<&Path>) -> Result<Self, ConfigError> {
        match path {
            None => Self::builtin(),
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(|source| ConfigError::Read {
                    path: p.to_path_buf(),
                    source,
                })?;
                Self::from_toml_str(&text).map_err(|e| ConfigError::InFile {
                    path: p.to_path_buf(),
                    error: Box::new(e),
                })
            }
        }
    }

    /// Checks every value's range, section by section; the message names the key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.control.validate()?;
        self.plant.validate()?;
        self.payload.validate()?;
        self.master.validate()?;
        if self.output.trace_every_ticks == 0 {
            return Err(ConfigError::TraceEvery);
        }
        self.accuracy.validate()?;
        validate_laparoscope(&self.scenario.laparoscope)?;
        self.scenario.step.validate()?;
        self.scenario.box_sweep.validate()?;
        self.scenario.payload.validate()
    }

    /// The control period, s.
    pub fn control_dt(&self) -> f64 {
        1.0 / self.control.rate_hz
    }

    /// The plant step, s.
    pub fn plant_dt(&self) -> f64 {
        self.control_dt() / f64::from(self.control.plant_steps_per_tick)
    }

    /// The output directory of `scenario`: `--out` if given, else `output.dir`, else
    /// `target/sim/<scenario>` in the binary's cargo target directory.
    pub fn output_dir(&self, out: Option<&Path>, scenario: &str) -> PathBuf {
        if let Some(o) = out {
            return o.to_path_buf();
        }
        if !self.output.dir.is_empty() {
            return PathBuf::from(&self.output.dir);
        }
        default_target_dir().join("sim").join(scenario)
    }
}

/// The cargo target directory the binary was built in (`<target>/<profile>/host-sim`
/// whose `<target>` holds cargo's `CACHEDIR.TAG`), else `./target`.
pub fn default_target_dir() -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|exe| {
            exe.ancestors()
                .skip(1)
                .take(3)
                .find(|d| d.join("CACHEDIR.TAG").is_file())
                .map(Path::to_path_buf)
        })
        .unwrap_or_else(|| PathBuf::from("target"))
}

impl ControlSection {
    fn validate(&self) -> Result<(), ConfigError> {
        range("control.rate_hz", self.rate_hz, 100.0, 10_000.0)?;
        if self.plant_steps_per_tick < 10 || self.plant_steps_per_tick > 1000 {
            return Err(ConfigError::PlantSteps(self.plant_steps_per_tick));
        }
        range(
            "control.compensated_leg_backlash_mm",
            self.compensated_leg_backlash_mm,
            0.0,
            1.0,
        )
    }
}

impl PlantSection {
    fn validate(&self) -> Result<(), ConfigError> {
        range("plant.leg_backlash_mm", self.leg_backlash_mm, 0.0, 1.0)?;
        if !matches!(self.payload_update.as_str(), "moved" | "tick" | "step") {
            return Err(ConfigError::PayloadUpdate(self.payload_update.clone()));
        }
        range(
            "plant.payload_refresh_mm",
            self.payload_refresh_mm,
            0.0,
            10.0,
        )?;
        range(
            "plant.payload_refresh_deg",
            self.payload_refresh_deg,
            0.0,
            10.0,
        )
    }
}

impl PayloadSection {
    fn validate(&self) -> Result<(), ConfigError> {
        range("payload.mass_kg", self.mass_kg, 0.0, 20.0)?;
        range("payload.gravity_m_s2", self.gravity_m_s2, 0.0, 20.0)?;
        for (i, x) in self.lever_mm.iter().enumerate() {
            range(&format!("payload.lever_mm[{i}]"), *x, -1000.0, 1000.0)?;
        }
        Ok(())
    }
}

impl MasterSection {
    fn validate(&self) -> Result<(), ConfigError> {
        range("master.stream_rate_hz", self.stream_rate_hz, 1.0, 10_000.0)?;
        range("master.latency_ms", self.latency_ms, 0.0, 1000.0)?;
        positive("master.accel_mm_s2", self.accel_mm_s2)?;
        positive("master.angular_speed_deg_s", self.angular_speed_deg_s)?;
        positive("master.angular_accel_deg_s2", self.angular_accel_deg_s2)
    }
}

impl AccuracySection {
    fn validate(&self) -> Result<(), ConfigError> {
        positive("accuracy.tip_rms_mm", self.tip_rms_mm)?;
        positive("accuracy.tip_max_mm", self.tip_max_mm)?;
        positive("accuracy.judged_speed_mm_s", self.judged_speed_mm_s)
    }
}

/// `[scenario.laparoscope]`: the loop, the tilt, one scale per pass speed, the holds.
fn validate_laparoscope(l: &Laparoscope) -> Result<(), ConfigError> {
    for (i, h) in l.loop_size_mm.iter().enumerate() {
        range(
            &format!("scenario.laparoscope.loop_size_mm[{i}]"),
            *h,
            0.0,
            50.0,
        )?;
    }
    range("scenario.laparoscope.tilt_deg", l.tilt_deg, 0.0, 45.0)?;
    if l.pass_speeds_mm_s.is_empty() {
        return Err(ConfigError::NoPass);
    }
    if l.pass_speeds_mm_s.len() != l.pass_scales.len() {
        return Err(ConfigError::PassScales {
            speeds: l.pass_speeds_mm_s.len(),
            scales: l.pass_scales.len(),
        });
    }
    for (i, v) in l.pass_speeds_mm_s.iter().enumerate() {
        range(
            &format!("scenario.laparoscope.pass_speeds_mm_s[{i}]"),
            *v,
            0.1,
            100.0,
        )?;
    }
    for (i, s) in l.pass_scales.iter().enumerate() {
        range(
            &format!("scenario.laparoscope.pass_scales[{i}]"),
            *s,
            0.01,
            2.0,
        )?;
    }
    range("scenario.laparoscope.hold_s", l.hold_s, 0.0, 60.0)?;
    range("scenario.laparoscope.settle_s", l.settle_s, 0.0, 60.0)
}

impl StepSection {
    fn validate(&self) -> Result<(), ConfigError> {
        if self.steps_mm_deg.is_empty() {
            return Err(ConfigError::NoStep);
        }
        for (i, st) in self.steps_mm_deg.iter().enumerate() {
            for (k, x) in st.iter().enumerate() {
                range(
                    &format!("scenario.step.steps_mm_deg[{i}][{k}]"),
                    *x,
                    -60.0,
                    60.0,
                )?;
            }
        }
        range("scenario.step.hold_s", self.hold_s, 0.05, 60.0)?;
        positive("scenario.step.settle_band_mm", self.settle_band_mm)?;
        positive("scenario.step.settle_band_deg", self.settle_band_deg)
    }
}

impl BoxSweepSection {
    fn validate(&self) -> Result<(), ConfigError> {
        range("scenario.box_sweep.speed_mm_s", self.speed_mm_s, 0.1, 100.0)?;
        range("scenario.box_sweep.tilt_deg", self.tilt_deg, 0.0, 45.0)?;
        range("scenario.box_sweep.hold_s", self.hold_s, 0.0, 60.0)?;
        range("scenario.box_sweep.reach", self.reach, 0.0, 1.5)?;
        range("scenario.box_sweep.tail_s", self.tail_s, 0.0, 60.0)
    }
}

impl PayloadScenarioSection {
    fn validate(&self) -> Result<(), ConfigError> {
        range("scenario.payload.attach_s", self.attach_s, 0.0, 60.0)?;
        range("scenario.payload.hold_s", self.hold_s, 0.0, 60.0)?;
        range("scenario.payload.speed_mm_s", self.speed_mm_s, 0.1, 100.0)?;
        for (k, x) in self.move_to_mm_deg.iter().enumerate() {
            range(
                &format!("scenario.payload.move_to_mm_deg[{k}]"),
                *x,
                -1000.0,
                1000.0,
            )?;
        }
        Ok(())
    }
}

fn range(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange {
            key: key.to_string(),
            low: lo,
            high: hi,
            value: v,
        })
    }
}

fn positive(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::NotPositive {
            key: key.to_string(),
            value: v,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn defaults_parse_and_validate() {
        let c = SimConfig::builtin().unwrap();
        assert_eq!(c.control.rate_hz, 1000.0);
        assert_eq!(c.plant.leg_backlash_mm, 0.08);
        assert_eq!(c.plant.payload_update(), PayloadUpdate::Moved);
        assert_eq!(c.scenario.laparoscope.pass_speeds_mm_s, vec![2.5, 25.0]);
    }

    #[test]
    fn overlay_replaces_only_given_keys() {
        let c = SimConfig::from_toml_str("[control]\nrate_hz = 2000\n").unwrap();
        assert_eq!(c.control.rate_hz, 2000.0);
        assert_eq!(c.control.plant_steps_per_tick, 10);
    }

    #[test]
    fn errors_name_the_key() {
        let e = SimConfig::from_toml_str("[control]\nrate_hz = 20000.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("control.rate_hz"), "{e}");
        let e = SimConfig::from_toml_str("[control]\nrate = 1.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("control.rate"), "{e}");
        let e = SimConfig::from_toml_str("[plant]\nleg_backlash_mm = \"x\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("plant.leg_backlash_mm"), "{e}");
        let e = SimConfig::from_toml_str("[scenario.step]\nsteps_mm_deg = [[1, 2]]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("scenario.step.steps_mm_deg[0]"), "{e}");
        let e = SimConfig::from_toml_str("[payload]\nlever_mm = [1.0]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("payload.lever_mm"), "{e}");
        let e = SimConfig::from_toml_str("[plant]\npayload_update = \"x\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("plant.payload_update"), "{e}");
        let e = SimConfig::from_toml_str("[plant]\npayload_refresh_mm = -1.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("plant.payload_refresh_mm"), "{e}");
        let e = SimConfig::from_toml_str("[control]\nplant_steps_per_tick = 5\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("control.plant_steps_per_tick"), "{e}");
    }
}
