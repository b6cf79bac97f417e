//! The measurement file: joint readings paired with the marker pose an external tracker
//! measured, one pose per row (CSV with a header, mm and deg).
//!
//! | column | meaning |
//! | --- | --- |
//! | `l1_mm`, `l2_mm`, `l3_mm` | the legs as the board reports them (encoder readings) |
//! | `theta1_deg`, `theta2_deg`, `theta3_deg` | the rotating links as the board reports them |
//! | `x_mm`, `y_mm`, `z_mm` | the marker's position in the tracker's frame |
//! | `rx_deg`, `ry_deg`, `rz_deg` | the marker's orientation in the tracker's frame, rotation vector (optional) |
//! | `label` | free text (optional) |
//!
//! A file either has the three rotation columns or not; a row whose rotation cells are
//! empty is a **position-only** measurement (a laser tracker's reflector, one optical
//! marker), which constrains the robot through the marker's position alone. Columns may
//! come in any order; unknown and repeated columns are refused (a misspelt name would
//! otherwise be silently ignored, a repeated one read from either copy). Joint readings
//! outside the robot's ranges ([`JointRanges`], [`out_of_range`]) are a typo or a
//! different robot: the command line refuses them, or drops and lists them on request. `host-sim calibrate plan` writes the poses to visit; the operator
//! drives the robot to each, waits for it to settle, and records the board's joints and
//! the tracker's reading in one row.

use crate::rigid::Rigid;
use kinematics_core::Joints;
use nalgebra::Vector3;
use robot_config::units::{deg_to_rad, m_to_mm, mm_to_m, rad_to_deg};
use std::io::{Read, Write};
use thiserror::Error;

/// One measured pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// The joints the board reported (SI, q order: l1, l2, l3, θ1, θ2, θ3).
    pub joints: Joints<f64>,
    /// The marker's position in the tracker's frame, m.
    pub position: Vector3<f64>,
    /// The marker's orientation (rotation vector, rad), None for a position-only row.
    pub rotation: Option<Vector3<f64>>,
    /// The row's label, if any.
    pub label: Option<String>,
}

impl Measurement {
    /// The measured marker pose (identity rotation for a position-only row).
    pub fn marker(&self) -> Rigid {
        Rigid::new(self.position, self.rotation.unwrap_or_else(Vector3::zeros))
    }
    /// Residual rows this measurement gives (3 or 6).
    pub fn rows(&self) -> usize {
        if self.rotation.is_some() {
            6
        } else {
            3
        }
    }
}

/// What is wrong with a measurement file.
#[derive(Debug, Error)]
pub enum MeasurementError {
    #[error("measurements: {0}")]
    Csv(#[from] csv::Error),
    #[error("measurements: missing column {0}")]
    MissingColumn(&'static str),
    #[error("measurements: unknown column {0:?} (known: {KNOWN})")]
    UnknownColumn(String),
    #[error("measurements row {row}: {column}: {message}")]
    Value {
        row: usize,
        column: &'static str,
        message: String,
    },
    #[error("measurements: the column {0} appears more than once")]
    RepeatedColumn(String),
    #[error("measurements: no rows")]
    Empty,
}

/// The joint readings a measurement of this robot can have: the stroke and the link
/// angles of the limits, widened by a margin for the built robot's offsets (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointRanges {
    /// Shortest and longest leg, m.
    pub stroke: [f64; 2],
    /// Largest |θ_i| (central value 0 on the outer branch), rad.
    pub link_angle_max: f64,
    /// Added to both ends: a leg (m) and an angle (rad).
    pub margin: [f64; 2],
}

impl JointRanges {
    /// The ranges of `limits`, widened by 2 mm and 2 deg (four times the tolerances of a
    /// robot built to drawings).
    pub fn from_limits(limits: &kinematics_core::guards::Limits<f64>) -> Self {
        JointRanges {
            stroke: limits.stroke,
            link_angle_max: limits.link_angle_max,
            margin: [mm_to_m(2.0), deg_to_rad(2.0)],
        }
    }

    /// The range of joint `j` (q order) at the edge, mm or deg.
    pub fn edge_range(&self, j: usize) -> [f64; 2] {
        if j < 3 {
            [
                m_to_mm(self.stroke[0] - self.margin[0]),
                m_to_mm(self.stroke[1] + self.margin[0]),
            ]
        } else {
            let a = rad_to_deg(self.link_angle_max + self.margin[1]);
            [-a, a]
        }
    }
}

/// A joint reading outside its range.
#[derive(Clone, Debug, PartialEq, Error)]
#[error(
    "measurements row {row}: {column} = {value} is outside the robot's range {:.1} .. {:.1}",
    range[0],
    range[1]
)]
pub struct OutOfRange {
    /// The data row, from 1.
    pub row: usize,
    /// The column, e.g. `l1_mm`.
    pub column: &'static str,
    /// The reading, mm or deg.
    pub value: f64,
    /// The range, mm or deg.
    pub range: [f64; 2],
}

/// Every joint reading outside `ranges`, by row (from 1) and column.
pub fn out_of_range(rows: &[Measurement], ranges: &JointRanges) -> Vec<OutOfRange> {
    let mut out = Vec::new();
    for (k, m) in rows.iter().enumerate() {
        for (j, &column) in JOINTS.iter().enumerate() {
            let value = if j < 3 {
                m_to_mm(m.joints[j])
            } else {
                rad_to_deg(m.joints[j])
            };
            let range = ranges.edge_range(j);
            if !(range[0]..=range[1]).contains(&value) {
                out.push(OutOfRange {
                    row: k + 1,
                    column,
                    value,
                    range,
                });
            }
        }
    }
    out
}

const JOINTS: [&str; 6] = [
    "l1_mm",
    "l2_mm",
    "l3_mm",
    "theta1_deg",
    "theta2_deg",
    "theta3_deg",
];
const POSITION: [&str; 3] = ["x_mm", "y_mm", "z_mm"];
const ROTATION: [&str; 3] = ["rx_deg", "ry_deg", "rz_deg"];
const KNOWN: &str = "l1_mm..theta3_deg, x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg, label";

/// Reads a measurement file.
pub fn read(input: impl Read) -> Result<Vec<Measurement>, MeasurementError> {
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(input);
    let header = rdr.headers()?.clone();
    let find = |name: &str| header.iter().position(|h| h == name);
    for (i, h) in header.iter().enumerate() {
        if header.iter().skip(i + 1).any(|o| o == h) {
            return Err(MeasurementError::RepeatedColumn(h.to_string()));
        }
        let known =
            JOINTS.contains(&h) || POSITION.contains(&h) || ROTATION.contains(&h) || h == "label";
        if !known {
            return Err(MeasurementError::UnknownColumn(h.to_string()));
        }
    }
    let col = |name: &'static str| find(name).ok_or(MeasurementError::MissingColumn(name));
    let joints: Vec<usize> = JOINTS.iter().map(|n| col(n)).collect::<Result<_, _>>()?;
    let position: Vec<usize> = POSITION.iter().map(|n| col(n)).collect::<Result<_, _>>()?;
    let rotation: Option<Vec<usize>> = if ROTATION.iter().any(|n| find(n).is_some()) {
        Some(ROTATION.iter().map(|n| col(n)).collect::<Result<_, _>>()?)
    } else {
        None
    };
    let label = find("label");
    let mut out = Vec::new();
    for (k, rec) in rdr.records().enumerate() {
        let rec = rec?;
        let row = k + 1;
        let cell = |i: usize| rec.get(i).unwrap_or("");
        let number = |i: usize, column: &'static str| -> Result<f64, MeasurementError> {
            let s = cell(i);
            let v: f64 = s.parse().map_err(|_| MeasurementError::Value {
                row,
                column,
                message: format!("{s:?} is not a number"),
            })?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(MeasurementError::Value {
                    row,
                    column,
                    message: "not finite".into(),
                })
            }
        };
        let mut q = Joints::zeros();
        for (j, (&i, &name)) in joints.iter().zip(JOINTS.iter()).enumerate() {
            let v = number(i, name)?;
            q[j] = if j < 3 { mm_to_m(v) } else { deg_to_rad(v) };
        }
        let mut p = Vector3::zeros();
        for (j, (&i, &name)) in position.iter().zip(POSITION.iter()).enumerate() {
            p[j] = mm_to_m(number(i, name)?);
        }
        let rot = match &rotation {
            Some(cols) if cols.iter().all(|&i| cell(i).is_empty()) => None,
            Some(cols) => {
                let mut r = Vector3::zeros();
                for (j, (&i, &name)) in cols.iter().zip(ROTATION.iter()).enumerate() {
                    r[j] = deg_to_rad(number(i, name)?);
                }
                Some(r)
            }
            None => None,
        };
        out.push(Measurement {
            joints: q,
            position: p,
            rotation: rot,
            label: label.map(|i| cell(i).to_string()).filter(|s| !s.is_empty()),
        });
    }
    if out.is_empty() {
        return Err(MeasurementError::Empty);
    }
    Ok(out)
}

/// Writes measurements in the format [`read`] takes (rotation columns when any row has
/// one).
pub fn write(out: impl Write, rows: &[Measurement]) -> Result<(), MeasurementError> {
    let mut w = csv::Writer::from_writer(out);
    let with_rotation = rows.iter().any(|m| m.rotation.is_some());
    let mut header: Vec<&str> = JOINTS.to_vec();
    header.extend(POSITION);
    if with_rotation {
        header.extend(ROTATION);
    }
    header.push("label");
    w.write_record(&header)?;
    for m in rows {
        let mut rec: Vec<String> = (0..6)
            .map(|j| {
                let v = if j < 3 {
                    m_to_mm(m.joints[j])
                } else {
                    rad_to_deg(m.joints[j])
                };
                format!("{v:.9}")
            })
            .collect();
        rec.extend(m.position.iter().map(|v| format!("{:.9}", m_to_mm(*v))));
        if with_rotation {
            match m.rotation {
                Some(r) => rec.extend(r.iter().map(|v| format!("{:.9}", rad_to_deg(*v)))),
                None => rec.extend([String::new(), String::new(), String::new()]),
            }
        }
        rec.push(m.label.clone().unwrap_or_default());
        w.write_record(&rec)?;
    }
    w.flush().map_err(|e| MeasurementError::Csv(e.into()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn round_trip_and_position_only_rows() {
        let rows = vec![
            Measurement {
                joints: Joints::new(0.17, 0.171, 0.172, 0.01, -0.02, 0.03),
                position: Vector3::new(0.5, -0.2, 1.1),
                rotation: Some(Vector3::new(0.1, 0.2, -0.3)),
                label: Some("p1".into()),
            },
            Measurement {
                joints: Joints::new(0.18, 0.171, 0.172, 0.01, -0.02, 0.03),
                position: Vector3::new(0.51, -0.2, 1.1),
                rotation: None,
                label: None,
            },
        ];
        let mut buf = Vec::new();
        write(&mut buf, &rows).unwrap();
        let back = read(buf.as_slice()).unwrap();
        assert_eq!(back.len(), 2);
        assert!(back[1].rotation.is_none() && back[0].rotation.is_some());
        assert!((back[0].joints - rows[0].joints).norm() < 1e-9);
        assert_eq!(back[0].rows() + back[1].rows(), 9);
    }

    #[test]
    fn errors_name_row_and_column() {
        let e = read("l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg,x_mm,y_mm,z_mm\n1,2,3,4,5,6,7,x,9\n".as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("row 1") && e.contains("y_mm"), "{e}");
        let e = read("l1_mm,foo\n".as_bytes()).unwrap_err().to_string();
        assert!(e.contains("foo"), "{e}");
        let e = read("l1_mm,l2_mm\n".as_bytes()).unwrap_err().to_string();
        assert!(e.contains("l3_mm"), "{e}");
    }

    #[test]
    fn a_repeated_column_is_refused() {
        let e = read(
            "l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg,x_mm,y_mm,z_mm,x_mm\n".as_bytes(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("x_mm appears more than once"), "{e}");
    }

    #[test]
    fn a_typo_in_a_leg_is_out_of_range_with_row_and_column() {
        let text = "l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg,x_mm,y_mm,z_mm\n\
                    170.9,170.9,170.9,0,0,0,1,2,3\n100,170.9,170.9,0,0,95,1,2,3\n";
        let rows = read(text.as_bytes()).unwrap();
        let ranges = JointRanges::from_limits(&kinematics_core::guards::Limits::reference());
        let bad = out_of_range(&rows, &ranges);
        assert_eq!(bad.len(), 2, "{bad:?}");
        assert_eq!((bad[0].row, bad[0].column), (2, "l1_mm"));
        assert_eq!((bad[1].row, bad[1].column), (2, "theta3_deg"));
        let e = bad[0].to_string();
        assert!(
            e.contains("row 2: l1_mm = 100 is outside the robot's range 142.0 .. 212.0"),
            "{e}"
        );
    }
}
