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
        Self::with_eccentricity(0.0, rb, rp, hc)
    }

    /// Both robots with eccentricity e (m) and the given rb, rp and hc (m).
    pub fn with_eccentricity(e: f64, rb: f64, rp: f64, hc: f64) -> Result<Self, PairError> {
        Ok(Pair {
            rspr: RsprGeometry::new(e, rb, rp, hc).map_err(PairError::Rspr)?,
            rrps: RrpsGeometry::new(e, rb, rp, hc).map_err(PairError::Rrps)?,
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

/// Three readings of a group of actuators' efforts along the path (N or N m), over the
/// samples both robots computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Readings {
    /// The largest |τ_j| over the path and the group.
    pub peak: f64,
    /// The mean of |τ_j| over the path and the group.
    pub mean: f64,
    /// The largest range max τ_j - min τ_j along the path over the group.
    pub peak_to_peak: f64,
}

/// The readings of joints `group` (0..3 the legs, 3..6 the rotary joints) over the
/// samples where both robots have a result.
pub fn readings<E, F>(
    a: &[PathSample<E>],
    b: &[PathSample<F>],
    group: std::ops::Range<usize>,
) -> (Readings, Readings) {
    let both: Vec<([f64; 6], [f64; 6])> = a
        .iter()
        .zip(b)
        .filter_map(|(x, y)| Some((*x.tau.as_ref().ok()?, *y.tau.as_ref().ok()?)))
        .collect();
    type Both = ([f64; 6], [f64; 6]);
    let read = |pick: &dyn Fn(&Both) -> [f64; 6]| {
        let (mut peak, mut sum, mut n, mut p2p) = (0.0f64, 0.0, 0usize, 0.0f64);
        for j in group.clone() {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for s in &both {
                let v = pick(s)[j];
                peak = peak.max(v.abs());
                sum += v.abs();
                n += 1;
                lo = lo.min(v);
                hi = hi.max(v);
            }
            if hi >= lo {
                p2p = p2p.max(hi - lo);
            }
        }
        Readings {
            peak,
            mean: if n > 0 { sum / n as f64 } else { f64::NAN },
            peak_to_peak: p2p,
        }
    };
    (read(&|s| s.0), read(&|s| s.1))
}

/// 1 - RSPR / RRPS of each reading: the fraction the RSPR needs less.
pub fn reductions(rspr: &Readings, rrps: &Readings) -> [f64; 3] {
    [
        1.0 - rspr.peak / rrps.peak,
        1.0 - rspr.mean / rrps.mean,
        1.0 - rspr.peak_to_peak / rrps.peak_to_peak,
    ]
}

/// The reductions table of `compare`: rotary torque and leg force, peak, mean and
/// peak-to-peak, for each pair (labelled by its eccentricities).
pub fn readings_table(pairs: &[Pair], spec: &PathSpec) -> String {
    let mut s = String::from(
        "  reduction 1 - RSPR/RRPS    peak      mean   peak-to-peak   (e: RSPR/RRPS, mm)\n",
    );
    for pair in pairs {
        let c = compare_along(pair, spec);
        let label = if pair.rspr.e == pair.rrps.e {
            format!("e={}", m_to_mm(pair.rspr.e))
        } else {
            format!("e={}/{}", m_to_mm(pair.rspr.e), m_to_mm(pair.rrps.e))
        };
        for (name, group) in [("rotary torque", 3..6), ("leg force", 0..3)] {
            let (a, b) = readings(&c.rspr, &c.rrps, group);
            let [p, m, q] = reductions(&a, &b);
            s.push_str(&format!(
                "  {name:<14} {label:<9} {:>7.1}% {:>8.1}% {:>10.1}%\n",
                p * 100.0,
                m * 100.0,
                q * 100.0
            ));
        }
    }
    s
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

/// What the table says about the thesis's "about 37 % less" (Appendix A, Fig. 4.4).
pub const THESIS_READING: &str = "  thesis: about 37% less rotary torque (Fig. 4.4); see \
the design README for which reading gives it\n";

/// Runs `compare`: both robots of `pair` along the path of `spec`, `compare.csv` and
/// `compare.png` written to `out` (default `target/design/compare`). Returns the summary
/// to print.
pub fn run(pair: &Pair, spec: &PathSpec, out: Option<&Path>) -> Result<String, OutputError> {
    run_with(pair, &[], spec, out)
}

/// [`run`], adding the reductions table for `pair` and each of `others`.
pub fn run_with(
    pair: &Pair,
    others: &[Pair],
    spec: &PathSpec,
    out: Option<&Path>,
) -> Result<String, OutputError> {
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
    let mut all = vec![*pair];
    all.extend_from_slice(others);
    text.push_str(&readings_table(&all, spec));
    text.push_str(THESIS_READING);
    text.push_str(&format!("  wrote {}\n", csv_path.display()));
    text.push_str(&format!("  wrote {}\n", png.display()));
    Ok(text)
}
