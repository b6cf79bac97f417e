//! The simulation settings: `host-sim/sim/default.toml` (embedded) overlaid with the keys
//! of a `--config FILE`, then validated.
//!
//! The embedded file is the schema: a key that it does not have is unknown, and a value
//! must have the type of the default it replaces (an integer may stand for a float). Every
//! error names the key by its dotted path (`control.rate_hz`, `scenario.step.hold_s`).

use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The embedded default settings (also the schema of a `--config` file).
pub const DEFAULT_TOML: &str = include_str!("../../sim/default.toml");

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
    /// that motion, which the thresholds bound (see `host-sim/sim/default.toml`).
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
    pub laparoscope: LaparoscopeSection,
    pub step: StepSection,
    pub box_sweep: BoxSweepSection,
    pub payload: PayloadScenarioSection,
    pub backlash_off: BacklashOffSection,
}

/// `[scenario.laparoscope]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LaparoscopeSection {
    pub loop_size_mm: [f64; 3],
    pub tilt_deg: f64,
    pub pass_speeds_mm_s: Vec<f64>,
    pub pass_scales: Vec<f64>,
    pub hold_s: f64,
    pub settle_s: f64,
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

fn type_name(v: &toml::Value) -> &'static str {
    match v {
        toml::Value::String(_) => "a string",
        toml::Value::Integer(_) => "an integer",
        toml::Value::Float(_) => "a number",
        toml::Value::Boolean(_) => "true or false",
        toml::Value::Datetime(_) => "a date",
        toml::Value::Array(_) => "an array",
        toml::Value::Table(_) => "a table",
    }
}

/// Arrays whose length is fixed (the elements of an array of arrays are too).
const FIXED_LENGTH: [&str; 3] = [
    "payload.lever_mm",
    "scenario.laparoscope.loop_size_mm",
    "scenario.payload.move_to_mm_deg",
];

/// Checks `value` against the schema value `default` and returns the value to store.
fn conform(key: &str, default: &toml::Value, value: toml::Value) -> Result<toml::Value, String> {
    use toml::Value as V;
    match (default, value) {
        (V::Table(d), V::Table(v)) => {
            let mut out = d.clone();
            overlay(key, &mut out, v)?;
            Ok(V::Table(out))
        }
        (V::Float(_), V::Integer(i)) => Ok(V::Float(i as f64)),
        (V::Array(d), V::Array(v)) => {
            if (FIXED_LENGTH.contains(&key) || key.ends_with(']')) && d.len() != v.len() {
                return Err(format!(
                    "`{key}` must have {} elements, not {}",
                    d.len(),
                    v.len()
                ));
            }
            // The elements must have the type of the default's first element.
            let Some(proto) = d.first() else {
                return Ok(V::Array(v));
            };
            v.into_iter()
                .enumerate()
                .map(|(i, x)| conform(&format!("{key}[{i}]"), proto, x))
                .collect::<Result<Vec<_>, _>>()
                .map(V::Array)
        }
        (d, v) if std::mem::discriminant(d) == std::mem::discriminant(&v) => Ok(v),
        (d, v) => Err(format!(
            "`{key}` must be {}, not {}",
            type_name(d),
            type_name(&v)
        )),
    }
}

/// Overlays the keys of `user` onto `base` (a table of the schema at `prefix`).
fn overlay(prefix: &str, base: &mut toml::Table, user: toml::Table) -> Result<(), String> {
    for (k, v) in user {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        let Some(default) = base.get(&k) else {
            let known: Vec<&str> = base.keys().map(String::as_str).collect();
            return Err(format!(
                "unknown key `{key}` (known here: {})",
                known.join(", ")
            ));
        };
        let merged = conform(&key, default, v)?;
        base.insert(k, merged);
    }
    Ok(())
}

fn parse_table(text: &str, what: &str) -> Result<toml::Table, String> {
    text.parse::<toml::Table>()
        .map_err(|e| format!("{what} is not valid TOML: {e}"))
}

impl SimConfig {
    /// The embedded defaults (`host-sim/sim/default.toml`).
    pub fn builtin() -> Result<Self, String> {
        Self::from_toml_str("")
    }

    /// The defaults overlaid with the keys of `text` (a `--config` file), validated.
    pub fn from_toml_str(text: &str) -> Result<Self, String> {
        let mut base = parse_table(DEFAULT_TOML, "the embedded default.toml")?;
        let user = parse_table(text, "the configuration")?;
        overlay("", &mut base, user)?;
        let cfg: SimConfig = toml::Value::Table(base)
            .try_into()
            .map_err(|e: toml::de::Error| format!("configuration: {}", e.message()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads `path` (or the defaults when `None`).
    pub fn load(path: Option<&Path>) -> Result<Self, String> {
        match path {
            None => Self::builtin(),
            Some(p) => {
                let text = std::fs::read_to_string(p)
                    .map_err(|e| format!("cannot read the config {}: {e}", p.display()))?;
                Self::from_toml_str(&text).map_err(|e| format!("config {}: {e}", p.display()))
            }
        }
    }

    /// Checks every value's range; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let c = &self.control;
        range("control.rate_hz", c.rate_hz, 100.0, 10_000.0)?;
        if c.plant_steps_per_tick < 10 || c.plant_steps_per_tick > 1000 {
            return Err(format!(
                "`control.plant_steps_per_tick` must be within 10 .. 1000 (the plant runs at \
                 least 10x the control rate), got {}",
                c.plant_steps_per_tick
            ));
        }
        range(
            "control.compensated_leg_backlash_mm",
            c.compensated_leg_backlash_mm,
            0.0,
            1.0,
        )?;
        range(
            "plant.leg_backlash_mm",
            self.plant.leg_backlash_mm,
            0.0,
            1.0,
        )?;
        if !matches!(
            self.plant.payload_update.as_str(),
            "moved" | "tick" | "step"
        ) {
            return Err(format!(
                "`plant.payload_update` must be \"moved\", \"tick\" or \"step\", got {:?}",
                self.plant.payload_update
            ));
        }
        range(
            "plant.payload_refresh_mm",
            self.plant.payload_refresh_mm,
            0.0,
            10.0,
        )?;
        range(
            "plant.payload_refresh_deg",
            self.plant.payload_refresh_deg,
            0.0,
            10.0,
        )?;
        let p = &self.payload;
        range("payload.mass_kg", p.mass_kg, 0.0, 20.0)?;
        range("payload.gravity_m_s2", p.gravity_m_s2, 0.0, 20.0)?;
        for (i, x) in p.lever_mm.iter().enumerate() {
            range(&format!("payload.lever_mm[{i}]"), *x, -1000.0, 1000.0)?;
        }
        let m = &self.master;
        range("master.stream_rate_hz", m.stream_rate_hz, 1.0, 10_000.0)?;
        range("master.latency_ms", m.latency_ms, 0.0, 1000.0)?;
        positive("master.accel_mm_s2", m.accel_mm_s2)?;
        positive("master.angular_speed_deg_s", m.angular_speed_deg_s)?;
        positive("master.angular_accel_deg_s2", m.angular_accel_deg_s2)?;
        if self.output.trace_every_ticks == 0 {
            return Err("`output.trace_every_ticks` must be at least 1".into());
        }
        let a = &self.accuracy;
        positive("accuracy.tip_rms_mm", a.tip_rms_mm)?;
        positive("accuracy.tip_max_mm", a.tip_max_mm)?;
        positive("accuracy.judged_speed_mm_s", a.judged_speed_mm_s)?;
        let l = &self.scenario.laparoscope;
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
            return Err("`scenario.laparoscope.pass_speeds_mm_s` needs at least one pass".into());
        }
        if l.pass_speeds_mm_s.len() != l.pass_scales.len() {
            return Err(format!(
                "`scenario.laparoscope.pass_scales` must have one entry per pass speed ({}), \
                 got {}",
                l.pass_speeds_mm_s.len(),
                l.pass_scales.len()
            ));
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
        range("scenario.laparoscope.settle_s", l.settle_s, 0.0, 60.0)?;
        let s = &self.scenario.step;
        if s.steps_mm_deg.is_empty() {
            return Err("`scenario.step.steps_mm_deg` needs at least one step".into());
        }
        for (i, st) in s.steps_mm_deg.iter().enumerate() {
            for (k, x) in st.iter().enumerate() {
                range(
                    &format!("scenario.step.steps_mm_deg[{i}][{k}]"),
                    *x,
                    -60.0,
                    60.0,
                )?;
            }
        }
        range("scenario.step.hold_s", s.hold_s, 0.05, 60.0)?;
        positive("scenario.step.settle_band_mm", s.settle_band_mm)?;
        positive("scenario.step.settle_band_deg", s.settle_band_deg)?;
        let b = &self.scenario.box_sweep;
        range("scenario.box_sweep.speed_mm_s", b.speed_mm_s, 0.1, 100.0)?;
        range("scenario.box_sweep.tilt_deg", b.tilt_deg, 0.0, 45.0)?;
        range("scenario.box_sweep.hold_s", b.hold_s, 0.0, 60.0)?;
        range("scenario.box_sweep.reach", b.reach, 0.0, 1.5)?;
        range("scenario.box_sweep.tail_s", b.tail_s, 0.0, 60.0)?;
        let p = &self.scenario.payload;
        range("scenario.payload.attach_s", p.attach_s, 0.0, 60.0)?;
        range("scenario.payload.hold_s", p.hold_s, 0.0, 60.0)?;
        range("scenario.payload.speed_mm_s", p.speed_mm_s, 0.1, 100.0)?;
        for (k, x) in p.move_to_mm_deg.iter().enumerate() {
            range(
                &format!("scenario.payload.move_to_mm_deg[{k}]"),
                *x,
                -1000.0,
                1000.0,
            )?;
        }
        Ok(())
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

fn range(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(format!("`{key}` must be within {lo} .. {hi}, got {v}"))
    }
}

fn positive(key: &str, v: f64) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("`{key}` must be finite and > 0, got {v}"))
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
        let e = SimConfig::from_toml_str("[control]\nrate_hz = 20000.0\n").unwrap_err();
        assert!(e.contains("control.rate_hz"), "{e}");
        let e = SimConfig::from_toml_str("[control]\nrate = 1.0\n").unwrap_err();
        assert!(e.contains("control.rate"), "{e}");
        let e = SimConfig::from_toml_str("[plant]\nleg_backlash_mm = \"x\"\n").unwrap_err();
        assert!(e.contains("plant.leg_backlash_mm"), "{e}");
        let e = SimConfig::from_toml_str("[scenario.step]\nsteps_mm_deg = [[1, 2]]\n").unwrap_err();
        assert!(e.contains("scenario.step.steps_mm_deg[0]"), "{e}");
        let e = SimConfig::from_toml_str("[payload]\nlever_mm = [1.0]\n").unwrap_err();
        assert!(e.contains("payload.lever_mm"), "{e}");
        let e = SimConfig::from_toml_str("[plant]\npayload_update = \"x\"\n").unwrap_err();
        assert!(e.contains("plant.payload_update"), "{e}");
        let e = SimConfig::from_toml_str("[plant]\npayload_refresh_mm = -1.0\n").unwrap_err();
        assert!(e.contains("plant.payload_refresh_mm"), "{e}");
        let e = SimConfig::from_toml_str("[control]\nplant_steps_per_tick = 5\n").unwrap_err();
        assert!(e.contains("control.plant_steps_per_tick"), "{e}");
    }
}
