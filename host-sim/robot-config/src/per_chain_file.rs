//! The per-chain (calibrated) geometry file: an RSPR robot whose chains each have their own
//! dimensions and encoder zero offsets ([`PerChainGeometry`]), in TOML, mm and deg, as
//! `host-sim calibrate` writes it and `--geometry` reads it.
//!
//! ```toml
//! robot = "rspr-per-chain"
//!
//! [calibration]              # optional
//! version = 3                # the calibration's version: the board stores and reports it
//! source = "host-sim calibrate poses.csv"
//!
//! [nominal]                  # the drawing (scales of the measures, central pose)
//! e_mm = 20.0
//! rb_mm = 90.0
//! rp_mm = 50.0
//! hc_mm = 160.0
//!
//! [[chain]]                  # exactly three, chain 1 first; frames of CONVENTIONS.md
//! base_pivot_mm = [20.0, 0.0, 0.0]      # c_i in {0}: the link's axis in its circle's plane
//! base_axis = [0.0, 0.0, 1.0]           # a_i in {0}, unit
//! link_length_mm = 90.0                 # rb_i
//! platform_joint_mm = [50.0, 0.0, 0.0]  # pp_i in {p}
//! platform_axis = [0.0, 1.0, 0.0]       # r_i in {p}, unit
//! leg_offset_mm = 0.0                   # |p_i - b_i| = l_i + leg_offset + leg_zero
//! leg_zero_mm = 0.0                     # the leg encoder's zero offset
//! link_zero_deg = 0.0                   # theta_i = phi_i - link_zero
//! ```
//!
//! The model is `kinematics_core::chain_geometry`'s. Unknown keys are refused; every error
//! names the key.

use crate::toml_error::TomlError;
use crate::units::{deg_to_rad, m_to_mm, mm_to_m, rad_to_deg};
use kinematics_core::{Chain, ChainDimensions, PerChain, PerChainGeometry, RsprGeometry};
use nalgebra::Vector3;
use serde::Deserialize;
use std::fmt::Write;

/// The `[calibration]` table: where the geometry came from.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationInfo {
    /// The calibration's version (the board stores and reports it); 0 when absent.
    #[serde(default)]
    pub version: u32,
    /// Free text: the measurements, the command.
    #[serde(default)]
    pub source: String,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Nominal {
    e_mm: f64,
    rb_mm: f64,
    rp_mm: f64,
    hc_mm: f64,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ChainTable {
    base_pivot_mm: [f64; 3],
    base_axis: [f64; 3],
    link_length_mm: f64,
    platform_joint_mm: [f64; 3],
    platform_axis: [f64; 3],
    leg_offset_mm: f64,
    leg_zero_mm: f64,
    link_zero_deg: f64,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[allow(dead_code)]
    robot: String,
    #[serde(default)]
    calibration: CalibrationInfo,
    nominal: Nominal,
    chain: Vec<ChainTable>,
}

/// What is wrong with a per-chain file (the file is named by the caller).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PerChainTextError {
    #[error(transparent)]
    Toml(#[from] TomlError),
    #[error("[[chain]]: {0} tables, exactly 3 are needed (chain 1, 2, 3)")]
    ChainCount(usize),
    #[error("[nominal]: {0}")]
    Nominal(kinematics_core::GeometryError),
    #[error("{0}")]
    Geometry(kinematics_core::GeometryError),
}

fn mm3(v: [f64; 3]) -> Vector3<f64> {
    Vector3::new(mm_to_m(v[0]), mm_to_m(v[1]), mm_to_m(v[2]))
}

/// Parses the text of a per-chain file.
pub fn parse(text: &str) -> Result<(PerChainGeometry<f64>, CalibrationInfo), PerChainTextError> {
    let f: File = toml::from_str(text).map_err(|e| TomlError::located(text, &e))?;
    let n = f.nominal;
    let nominal = RsprGeometry::new(
        mm_to_m(n.e_mm),
        mm_to_m(n.rb_mm),
        mm_to_m(n.rp_mm),
        mm_to_m(n.hc_mm),
    )
    .map_err(PerChainTextError::Nominal)?;
    let [c1, c2, c3] = <[ChainTable; 3]>::try_from(f.chain.clone())
        .map_err(|v| PerChainTextError::ChainCount(v.len()))?;
    let dims = |c: &ChainTable| ChainDimensions {
        base_pivot: mm3(c.base_pivot_mm),
        base_axis: Vector3::from(c.base_axis),
        link_length: mm_to_m(c.link_length_mm),
        platform_joint: mm3(c.platform_joint_mm),
        platform_axis: Vector3::from(c.platform_axis),
        leg_offset: mm_to_m(c.leg_offset_mm),
        leg_zero: mm_to_m(c.leg_zero_mm),
        link_zero: deg_to_rad(c.link_zero_deg),
    };
    let g = PerChainGeometry::new(nominal, PerChain([dims(&c1), dims(&c2), dims(&c3)]))
        .map_err(PerChainTextError::Geometry)?;
    Ok((g, f.calibration))
}

/// True when the text names the per-chain layout (`robot = "rspr-per-chain"`).
pub fn is_per_chain(text: &str) -> bool {
    #[derive(Deserialize)]
    struct Head {
        robot: Option<String>,
    }
    // Only the `robot` key matters here; the full parse reports any other problem.
    toml::from_str::<toml::Table>(text)
        .ok()
        .and_then(|t| t.try_into::<Head>().ok())
        .and_then(|h| h.robot)
        .is_some_and(|r| r == "rspr-per-chain")
}

/// The text of a per-chain file (what [`parse`] reads back to the same values to
/// 1e-12 m and 1e-12).
pub fn text(g: &PerChainGeometry<f64>, info: &CalibrationInfo, comment: &str) -> String {
    let mut s = String::new();
    for line in comment.lines() {
        let _ = writeln!(s, "# {line}");
    }
    let _ = writeln!(
        s,
        "# Per-chain RSPR geometry: mm and deg, frames of CONVENTIONS.md; the model is"
    );
    let _ = writeln!(
        s,
        "# kinematics-core's chain_geometry (host-sim/robot-config/src/per_chain_file.rs)."
    );
    let _ = writeln!(s, "robot = \"rspr-per-chain\"\n");
    let _ = writeln!(s, "[calibration]");
    let _ = writeln!(s, "version = {}", info.version);
    let _ = writeln!(s, "source = {:?}\n", info.source);
    let n = g.nominal();
    let _ = writeln!(s, "[nominal]");
    for (k, v) in [
        ("e_mm", n.e),
        ("rb_mm", n.rb),
        ("rp_mm", n.rp),
        ("hc_mm", n.hc),
    ] {
        let _ = writeln!(s, "{k} = {:?}", m_to_mm(v));
    }
    let v3 =
        |v: &Vector3<f64>, k: f64| format!("[{:.12}, {:.12}, {:.12}]", v.x * k, v.y * k, v.z * k);
    for c in Chain::ALL {
        let d = &g.chains()[c];
        let _ = writeln!(s, "\n[[chain]]  # {c}");
        let _ = writeln!(s, "base_pivot_mm = {}", v3(&d.base_pivot, 1e3));
        let _ = writeln!(s, "base_axis = {}", v3(&d.base_axis, 1.0));
        let _ = writeln!(s, "link_length_mm = {:.12}", m_to_mm(d.link_length));
        let _ = writeln!(s, "platform_joint_mm = {}", v3(&d.platform_joint, 1e3));
        let _ = writeln!(s, "platform_axis = {}", v3(&d.platform_axis, 1.0));
        let _ = writeln!(s, "leg_offset_mm = {:.12}", m_to_mm(d.leg_offset));
        let _ = writeln!(s, "leg_zero_mm = {:.12}", m_to_mm(d.leg_zero));
        let _ = writeln!(s, "link_zero_deg = {:.12}", rad_to_deg(d.link_zero));
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// The symmetric reference robot written and read back is the same robot, to the
    /// printed precision; a wrong chain count and an unknown key are named.
    #[test]
    fn round_trip_and_errors() {
        let g = PerChainGeometry::from(RsprGeometry::<f64>::reference());
        let info = CalibrationInfo {
            version: 7,
            source: "test".into(),
        };
        let t = text(&g, &info, "a test");
        assert!(is_per_chain(&t));
        let (back, back_info) = parse(&t).unwrap();
        assert_eq!(back_info, info);
        for c in Chain::ALL {
            let (a, b) = (&g.chains()[c], &back.chains()[c]);
            assert!((a.base_pivot - b.base_pivot).norm() < 1e-14);
            assert!((a.platform_axis - b.platform_axis).norm() < 1e-11);
            assert!((a.link_length - b.link_length).abs() < 1e-14);
        }
        let two = t.rsplit_once("[[chain]]").unwrap().0;
        assert!(matches!(parse(two), Err(PerChainTextError::ChainCount(2))));
        let bad = t.replace("leg_zero_mm", "leg_zeros_mm");
        let e = parse(&bad).unwrap_err().to_string();
        assert!(e.contains("leg_zeros_mm"), "{e}");
        let bad = t.replacen(
            "base_axis = [0.000000000000, 0.000000000000, 1.000000000000]",
            "base_axis = [0.0, 0.0, 2.0]",
            1,
        );
        let e = parse(&bad).unwrap_err().to_string();
        assert!(e.contains("chain 1 base_axis") && e.contains("unit"), "{e}");
    }
}
