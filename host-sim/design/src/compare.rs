//! `host-sim compare`: the RSPR with zero eccentricity against the RRPS robot of Alizade,
//! Tagiyev and Duffy (thesis Appendix A section 4, Fig. 4.4) along the thesis's diagonal
//! path: from [-20,-20,-10] to [20,20,10] mm about [0, 0, hc], the platform rotated 20 deg
//! about [1,1,1], wrench [7,7,7 N, 0.7,0.7,0.7 N m].
//!
//! Both robots get the selected RSPR's rb, rp and hc with e = 0 (by default the prototype's
//! 90, 50 and 160 mm). The RRPS geometry is documented in [`crate::rrps`].

use crate::files::{out_dir, write_csv, OutputError};
use crate::forces_path::{forces_along, peaks, PathSample, PathSpec, THESIS_WRENCH};
use crate::rrps::{
    rrps_actuator_forces, rrps_inverse, rrps_jacobian, RrpsGeometry, RrpsGeometryError, RrpsIkError,
};
use kinematics_core::{
    Branch, ForceError, GeometryError, JacobianError, Robot, RsprGeometry, Wrench,
};
use plots::{line_charts, span, Layout, Panel, PlotError, Series, CHAIN_COLORS};
use robot_config::edge::{pose_from_edge, EdgeError, POSE};
use robot_config::units::{fixed, m_to_mm, significant};
use std::path::Path;
use thiserror::Error;

/// The force columns of either robot in q order (legs, then rotary joints).
pub const TAU: [&str; 6] = ["f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm"];

/// A pair that cannot be built from the given dimensions.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum PairError {
    #[error("RSPR (e = 0): {0}")]
    Rspr(GeometryError),
    #[error("RRPS: {0}")]
    Rrps(RrpsGeometryError),
}

/// Why the RRPS's tau could not be computed at a pose.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum RrpsTauError {
    #[error(transparent)]
    Pose(#[from] EdgeError),
    #[error("rrps ik: {0}")]
    Ik(RrpsIkError),
    #[error("rrps jacobian: {0}")]
    Jacobian(JacobianError),
    #[error("rrps forces: {0}")]
    Forces(ForceError),
}

/// The two robots of the comparison, both with zero eccentricity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair {
    pub rspr: RsprGeometry<f64>,
    pub rrps: RrpsGeometry<f64>,
}

impl Pair {
    /// The zero-eccentricity RSPR and the RRPS with the given rb, rp and hc (m).
    pub fn new(rb: f64, rp: f64, hc: f64) -> Result<Self, PairError> {
        Ok(Pair {
            rspr: RsprGeometry::new(0.0, rb, rp, hc).map_err(PairError::Rspr)?,
            rrps: RrpsGeometry::new(0.0, rb, rp, hc).map_err(PairError::Rrps)?,
        })
    }

    /// The thesis's pair: rb = 90, rp = 50, hc = 160 mm, e = 0.
    pub fn thesis() -> Self {
        Pair {
            rspr: RsprGeometry {
                e: 0.0,
                ..RsprGeometry::reference()
            },
            rrps: RrpsGeometry::comparison(),
        }
    }
}

/// RRPS τ at one pose (edge units): N on the legs, N m on the rotary joints.
pub fn rrps_tau_at(
    g: &RrpsGeometry<f64>,
    pose_edge: [f64; 6],
    wrench: [f64; 6],
    branch: Branch,
    min_inv_cond: f64,
) -> Result<[f64; 6], RrpsTauError> {
    let pose = pose_from_edge(&POSE, pose_edge)?;
    let sol = rrps_inverse(g, &pose, branch).map_err(RrpsTauError::Ik)?;
    let jac = rrps_jacobian(g, &sol).map_err(RrpsTauError::Jacobian)?;
    let st = rrps_actuator_forces(&jac, g.rp, &Wrench::from(wrench), min_inv_cond)
        .map_err(RrpsTauError::Forces)?;
    let mut out = [0.0; 6];
    out.iter_mut().zip(st.tau.iter()).for_each(|(o, t)| *o = *t);
    Ok(out)
}

/// The comparison along a path.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// The RSPR (e = 0) samples.
    pub rspr: Vec<PathSample>,
    /// The RRPS samples (same poses).
    pub rrps: Vec<PathSample<RrpsTauError>>,
    /// Peak |τ_j| along the path per joint.
    pub rspr_peaks: [f64; 6],
    pub rrps_peaks: [f64; 6],
}

impl Comparison {
    /// Largest rotary torque of the RSPR over the path and the chains, N m.
    pub fn rspr_peak_torque(&self) -> f64 {
        max3(&self.rspr_peaks[3..])
    }
    /// Largest rotary torque of the RRPS over the path and the chains, N m.
    pub fn rrps_peak_torque(&self) -> f64 {
        max3(&self.rrps_peaks[3..])
    }
    /// Peak rotary torque RSPR / RRPS.
    pub fn torque_ratio(&self) -> f64 {
        self.rspr_peak_torque() / self.rrps_peak_torque()
    }
    /// Samples that failed on either robot.
    pub fn failed(&self) -> usize {
        self.rspr
            .iter()
            .zip(&self.rrps)
            .filter(|(a, b)| a.tau.is_err() || b.tau.is_err())
            .count()
    }
}

fn max3(v: &[f64]) -> f64 {
    v.iter()
        .fold(f64::NAN, |m, x| if m.is_nan() { *x } else { m.max(*x) })
}

/// Evaluates both robots along the path of `spec` (its from/to are about [0, 0, hc]).
pub fn compare_along(pair: &Pair, spec: &PathSpec) -> Comparison {
    let rspr = forces_along(&Robot::Rspr(pair.rspr), spec);
    let rrps: Vec<PathSample<RrpsTauError>> = rspr
        .iter()
        .map(|s| PathSample {
            s: s.s,
            pose: s.pose,
            tau: rrps_tau_at(
                &pair.rrps,
                s.pose,
                spec.wrench,
                spec.branch,
                spec.min_inv_cond,
            ),
        })
        .collect();
    Comparison {
        rspr_peaks: peaks(&rspr),
        rrps_peaks: peaks(&rrps),
        rspr,
        rrps,
    }
}

/// The CSV header: s, the pose, the RSPR then the RRPS forces, error.
pub fn header() -> Vec<String> {
    let mut h: Vec<String> = vec!["s".into()];
    h.extend(POSE.iter().map(|c| c.to_string()));
    for robot in ["rspr", "rrps"] {
        h.extend(TAU.iter().map(|c| format!("{robot}_{c}")));
    }
    h.push("error".into());
    h
}

fn rows(c: &Comparison) -> Vec<Vec<String>> {
    c.rspr
        .iter()
        .zip(&c.rrps)
        .map(|(a, b)| {
            let mut r = vec![fixed(a.s, 6)];
            r.extend(a.pose.iter().map(|&x| fixed(x, 6)));
            let mut errors = Vec::new();
            let taus = [
                ("rspr", a.tau.as_ref().map_err(|e| e.to_string())),
                ("rrps", b.tau.as_ref().map_err(|e| e.to_string())),
            ];
            for (name, tau) in taus {
                match tau {
                    Ok(t) => r.extend(t.iter().map(|&x| significant(x))),
                    Err(e) => {
                        r.extend(std::iter::repeat_n(String::new(), 6));
                        errors.push(format!("{name}: {e}"));
                    }
                }
            }
            r.push(errors.join("; "));
            r
        })
        .collect()
}

/// Plots the leg forces (top) and the rotary torques (bottom) of both robots against s:
/// RSPR thick, RRPS thin, one colour per chain.
pub fn plot(c: &Comparison, title: &str, path: &Path) -> Result<(), PlotError> {
    fn computed<E>(v: &[PathSample<E>]) -> Vec<(f64, [f64; 6])> {
        v.iter()
            .filter_map(|s| s.tau.as_ref().ok().map(|t| (s.s, *t)))
            .collect()
    }
    let (a, b) = (computed(&c.rspr), computed(&c.rrps));
    let panels: Vec<Panel> = (0..2)
        .map(|p| {
            let joints = 3 * p..3 * p + 3;
            let mut series = Vec::new();
            for (j, color) in joints.clone().zip(CHAIN_COLORS) {
                for (robot, data, width) in [("RSPR e=0", &a, 3), ("RRPS", &b, 1)] {
                    let points = data.iter().map(|(s, t)| (*s, t[j])).collect();
                    series.push(Series::new(
                        format!("{robot} {}", TAU[j]),
                        points,
                        color,
                        width,
                    ));
                }
            }
            Panel {
                levels: Vec::new(),
                bands: Vec::new(),
                caption: None,
                x_desc: "path parameter s".into(),
                y_desc: if p == 0 { "N" } else { "N m" }.into(),
                x_range: (0.0, 1.0),
                y_range: span(
                    a.iter()
                        .chain(&b)
                        .flat_map(|(_, t)| t[joints.clone()].to_vec()),
                ),
                series,
            }
        })
        .collect();
    line_charts(path, (1200, 900), title, &panels, Layout::Stacked)
}

/// The summary printed by `compare`.
pub fn summary(pair: &Pair, c: &Comparison) -> String {
    let mut s = format!(
        "RSPR (e = 0) vs RRPS, rb {} mm, rp {} mm, hc {} mm, along the diagonal: {} samples, \
         {} failed\n",
        m_to_mm(pair.rspr.rb),
        m_to_mm(pair.rspr.rp),
        m_to_mm(pair.rspr.hc),
        c.rspr.len(),
        c.failed()
    );
    s.push_str(&format!(
        "  {:<8} {:>14} {:>14}\n",
        "peak", "RSPR e=0", "RRPS"
    ));
    for (j, name) in TAU.iter().enumerate() {
        s.push_str(&format!(
            "  |{:<6}| {:>14.4} {:>14.4}\n",
            name, c.rspr_peaks[j], c.rrps_peaks[j]
        ));
    }
    let r = c.torque_ratio();
    s.push_str(&format!(
        "  peak rotary torque: RSPR {:.4} N m, RRPS {:.4} N m, ratio RSPR/RRPS = {:.4} \
         (RSPR needs {:.1}% less; thesis Fig. 4.4: about 37% less)\n",
        c.rspr_peak_torque(),
        c.rrps_peak_torque(),
        r,
        (1.0 - r) * 100.0
    ));
    s
}

/// Runs `compare`: both robots of `pair` along the path of `spec`, `compare.csv` and
/// `compare.png` written to `out` (default `target/design/compare`). Returns the summary
/// to print.
pub fn run(pair: &Pair, spec: &PathSpec, out: Option<&Path>) -> Result<String, OutputError> {
    let c = compare_along(pair, spec);
    let dir = out_dir(out, "compare")?;
    let csv_path = dir.join("compare.csv");
    write_csv(&csv_path, &header(), &rows(&c))?;
    let png = dir.join("compare.png");
    let wrench_note = if spec.wrench == THESIS_WRENCH {
        "thesis wrench".to_string()
    } else {
        format!("wrench {:?}", spec.wrench)
    };
    let title = format!(
        "RSPR e=0 (thick) vs RRPS (thin): diagonal path, 20 deg about [1,1,1], {wrench_note}"
    );
    plot(&c, &title, &png)?;
    let mut text = summary(pair, &c);
    text.push_str(&format!("  wrote {}\n", csv_path.display()));
    text.push_str(&format!("  wrote {}\n", png.display()));
    Ok(text)
}
