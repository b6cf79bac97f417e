//! `host-sim compare`: the RSPR with zero eccentricity against the RRPS robot of Alizade,
//! Tagiyev and Duffy (thesis Appendix A section 4, Fig. 4.4) along the thesis's diagonal
//! path: from [-20,-20,-10] to [20,20,10] mm about [0, 0, hc], the platform rotated 20 deg
//! about [1,1,1], wrench [7,7,7 N, 0.7,0.7,0.7 N m].
//!
//! Both robots get the selected RSPR's rb, rp and hc with e = 0 (by default the prototype's
//! 90, 50 and 160 mm). The RRPS geometry is documented in `design::rrps`.

use super::forces_path::{forces_along, peaks, PathSample, PathSpec, THESIS_WRENCH};
use super::{out_dir, perr, register_font, span, write_csv};
use crate::columns::{parse_branch, pose_from_edge, POSE};
use crate::task_box::numbers;
use crate::units::{fixed, m_to_mm, significant};
use ::design::rrps::{rrps_actuator_forces, rrps_inverse, rrps_jacobian, RrpsGeometry};
use clap::Args;
use kinematics_core::{Branch, Robot, RsprGeometry, Wrench};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// The force columns of either robot in q order (legs, then rotary joints).
pub const TAU: [&str; 6] = ["f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm"];

/// `host-sim compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Number of samples along the path (>= 2), ends included.
    #[arg(long, value_name = "N", default_value_t = 101)]
    pub samples: usize,
    /// Wrench fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm.
    #[arg(
        long,
        value_name = "FX,FY,FZ,TX,TY,TZ",
        default_value = "7,7,7,0.7,0.7,0.7",
        allow_hyphen_values = true
    )]
    pub wrench: String,
    /// Inverse-kinematics branch 0..=7 of both robots.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
    /// Output directory [default: target/design/compare].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// The two robots of the comparison, both with zero eccentricity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair {
    pub rspr: RsprGeometry<f64>,
    pub rrps: RrpsGeometry<f64>,
}

impl Pair {
    /// The zero-eccentricity RSPR and the RRPS with the given rb, rp and hc (m).
    pub fn new(rb: f64, rp: f64, hc: f64) -> Result<Self, String> {
        Ok(Pair {
            rspr: RsprGeometry::new(0.0, rb, rp, hc).map_err(|e| format!("RSPR (e = 0): {e}"))?,
            rrps: RrpsGeometry::new(0.0, rb, rp, hc).map_err(|e| format!("RRPS: {e}"))?,
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
) -> Result<[f64; 6], String> {
    let pose = pose_from_edge(&POSE, pose_edge)?;
    let sol = rrps_inverse(g, &pose, branch).map_err(|e| format!("rrps ik: {e}"))?;
    let jac = rrps_jacobian(g, &sol).map_err(|e| format!("rrps jacobian: {e}"))?;
    let st = rrps_actuator_forces(&jac, g.rp, &Wrench::from(wrench), min_inv_cond)
        .map_err(|e| format!("rrps forces: {e}"))?;
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
    pub rrps: Vec<PathSample>,
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
    let rrps: Vec<PathSample> = rspr
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
            for (name, smp) in [("rspr", a), ("rrps", b)] {
                match &smp.tau {
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
pub fn plot(c: &Comparison, title: &str, path: &Path) -> Result<(), String> {
    register_font();
    let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(perr)?;
    let root = root.titled(title, ("sans-serif", 18)).map_err(perr)?;
    let panels = root.split_evenly((2, 1));
    let colors = [RED, BLUE, RGBColor(0, 130, 0)];
    let ok = |v: &[PathSample]| -> Vec<(f64, [f64; 6])> {
        v.iter()
            .filter_map(|s| s.tau.as_ref().ok().map(|t| (s.s, *t)))
            .collect()
    };
    let (a, b) = (ok(&c.rspr), ok(&c.rrps));
    for (p, area) in panels.iter().enumerate() {
        let joints = 3 * p..3 * p + 3;
        let yr = span(
            a.iter()
                .chain(&b)
                .flat_map(|(_, t)| t[joints.clone()].to_vec()),
        );
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..1.0, yr.0..yr.1)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("path parameter s")
            .y_desc(if p == 0 { "N" } else { "N m" })
            .draw()
            .map_err(perr)?;
        for (j, color) in joints.zip(colors) {
            for (robot, data, width) in [("RSPR e=0", &a, 3), ("RRPS", &b, 1)] {
                chart
                    .draw_series(LineSeries::new(
                        data.iter().map(|(s, t)| (*s, t[j])),
                        color.stroke_width(width),
                    ))
                    .map_err(perr)?
                    .label(format!("{robot} {}", TAU[j]))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(width))
                    });
            }
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(perr)?;
    }
    root.present().map_err(perr)
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

/// Runs `compare` with the selected RSPR's rb, rp and hc (e set to 0).
pub fn run(args: &CompareArgs, robot: &Robot<f64>) -> Result<(), String> {
    let Robot::Rspr(g) = robot else {
        return Err(
            "compare needs an RSPR geometry (its rb, rp and hc are used with e = 0)".into(),
        );
    };
    if args.samples < 2 {
        return Err(format!("--samples: {} is below 2", args.samples));
    }
    let pair = Pair::new(g.rb, g.rp, g.hc)?;
    let spec = PathSpec {
        samples: args.samples,
        wrench: numbers("--wrench", &args.wrench)?,
        branch: parse_branch(&args.branch)?,
        ..PathSpec::thesis_diagonal()
    };
    let c = compare_along(&pair, &spec);
    let dir = out_dir(args.out.as_deref(), "compare")?;
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
    print!("{}", summary(&pair, &c));
    println!("  wrote {}", csv_path.display());
    println!("  wrote {}", png.display());
    Ok(())
}
