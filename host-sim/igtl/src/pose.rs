//! Poses on the wire (millimetres, float32) and inside (SI, f64), and the registration.
//!
//! Frame: a TRANSFORM or POSITION carries the pose of the platform frame {p} in the
//! *client frame*: the 4x4 matrix maps {p} coordinates to client coordinates, its
//! translation is the platform centre o_p in millimetres. By default the client frame is
//! the robot base frame {0} of the repository's `CONVENTIONS.md`. A [`Registration`]
//! (image or RAS to robot base, fixed) may be set: targets are mapped client → base before
//! they reach the robot, and measured poses base → client before they are sent.
//!
//! Values are checked, never silently mended: every number must be finite; a TRANSFORM's
//! 3x3 block must be a rotation to within [`ROTATION_TOLERANCE`] (float32 and the client's
//! own arithmetic leave a little noise, which is then removed by taking the nearest
//! rotation); a quaternion's norm must be 1 to within [`QUATERNION_TOLERANCE`] (then it is
//! normalised). Anything further off is refused with the size of the error.

use crate::content::{PositionContent, PositionOrientation, TransformContent};
use kinematics_core::pose::Pose;
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};
use serde::Deserialize;
use std::path::Path;
use thiserror::Error;

/// A pose in SI units: `t` in metres, `r` = wRp (CONVENTIONS.md "Pose").
pub type PoseSi = Pose<f64>;

/// Largest Frobenius norm of RᵀR − I accepted for a rotation block.
pub const ROTATION_TOLERANCE: f64 = 1e-4;
/// Largest deviation of a quaternion's norm from 1 accepted.
pub const QUATERNION_TOLERANCE: f64 = 1e-3;

const MM_PER_M: f64 = 1000.0;

/// Wire values that are not a pose.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum PoseError {
    /// A number is NaN or infinite.
    #[error("{field} holds a non-finite number")]
    NonFinite {
        /// Which field.
        field: &'static str,
    },
    /// The 3x3 block is not a rotation.
    #[error("the 3x3 block is not a rotation: |R^T R - I| = {deviation:.3e} (tolerance {ROTATION_TOLERANCE:e}; scaling and shear are not poses)")]
    NotRotation {
        /// Frobenius norm of RᵀR − I.
        deviation: f64,
    },
    /// The 3x3 block is a reflection (determinant −1).
    #[error("the 3x3 block is a reflection (determinant {det:.6})")]
    Reflection {
        /// Its determinant.
        det: f64,
    },
    /// A quaternion whose norm is not 1.
    #[error("the quaternion's norm is {norm:.6}, not 1 (tolerance {QUATERNION_TOLERANCE:e})")]
    NotUnitQuaternion {
        /// Its norm.
        norm: f64,
    },
}

/// A rigid-transform check of a 3x3 block: finite, orthonormal within tolerance, proper.
fn rotation_from_block(m: &Matrix3<f64>, field: &'static str) -> Result<Rotation3<f64>, PoseError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(PoseError::NonFinite { field });
    }
    let deviation = (m.transpose() * m - Matrix3::identity()).norm();
    if deviation > ROTATION_TOLERANCE {
        return Err(PoseError::NotRotation { deviation });
    }
    let det = m.determinant();
    if det < 0.0 {
        return Err(PoseError::Reflection { det });
    }
    Ok(Rotation3::from_matrix(m))
}

/// The pose a TRANSFORM carries, in metres.
pub fn pose_from_transform(t: &TransformContent) -> Result<PoseSi, PoseError> {
    let m = Matrix3::from_fn(|i, j| f64::from(t.rotation[i][j]));
    let p = Vector3::from_fn(|i, _| f64::from(t.translation_mm[i]));
    if p.iter().any(|v| !v.is_finite()) {
        return Err(PoseError::NonFinite {
            field: "translation",
        });
    }
    Ok(Pose {
        t: p / MM_PER_M,
        r: rotation_from_block(&m, "rotation")?,
    })
}

/// The TRANSFORM of a pose (float32, millimetres).
pub fn transform_from_pose(pose: &PoseSi) -> TransformContent {
    let m = pose.r.matrix();
    TransformContent {
        rotation: [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)] as f32)),
        translation_mm: [0, 1, 2].map(|i| (pose.t[i] * MM_PER_M) as f32),
    }
}

/// The position (metres) and, when given, orientation a POSITION carries. The 24-byte
/// form's `W` is `sqrt(1 - |v|^2)`, refused when `|v|` exceeds 1 by more than the
/// tolerance (the reference library substitutes the identity there).
pub fn target_from_position(
    p: &PositionContent,
) -> Result<(Vector3<f64>, Option<Rotation3<f64>>), PoseError> {
    let t = Vector3::from_fn(|i, _| f64::from(p.position_mm[i]));
    if t.iter().any(|v| !v.is_finite()) {
        return Err(PoseError::NonFinite { field: "position" });
    }
    let q = match p.orientation {
        PositionOrientation::None => return Ok((t / MM_PER_M, None)),
        PositionOrientation::Quaternion3([x, y, z]) => {
            let v = Vector3::new(f64::from(x), f64::from(y), f64::from(z));
            if v.iter().any(|c| !c.is_finite()) {
                return Err(PoseError::NonFinite {
                    field: "quaternion",
                });
            }
            let w2 = 1.0 - v.norm_squared();
            if w2 < -2.0 * QUATERNION_TOLERANCE {
                return Err(PoseError::NotUnitQuaternion { norm: v.norm() });
            }
            // Within tolerance, a slightly negative w^2 is rounding: w = 0.
            Quaternion::new(w2.max(0.0).sqrt(), v.x, v.y, v.z)
        }
        PositionOrientation::Quaternion([x, y, z, w]) => {
            let q = Quaternion::new(f64::from(w), f64::from(x), f64::from(y), f64::from(z));
            if q.coords.iter().any(|c| !c.is_finite()) {
                return Err(PoseError::NonFinite {
                    field: "quaternion",
                });
            }
            q
        }
    };
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_TOLERANCE {
        return Err(PoseError::NotUnitQuaternion { norm });
    }
    Ok((
        t / MM_PER_M,
        Some(UnitQuaternion::from_quaternion(q).to_rotation_matrix()),
    ))
}

/// The 28-byte POSITION of a pose (float32, millimetres, quaternion with `W >= 0`).
pub fn position_from_pose(pose: &PoseSi) -> PositionContent {
    let q = UnitQuaternion::from_rotation_matrix(&pose.r);
    let q = if q.w < 0.0 {
        -q.into_inner()
    } else {
        q.into_inner()
    };
    PositionContent {
        position_mm: [0, 1, 2].map(|i| (pose.t[i] * MM_PER_M) as f32),
        orientation: PositionOrientation::Quaternion([
            q.i as f32, q.j as f32, q.k as f32, q.w as f32,
        ]),
    }
}

/// A registration that cannot be used.
#[derive(Debug, Error)]
pub enum RegistrationError {
    /// Not 16 numbers.
    #[error("a registration matrix has 16 numbers (4x4, row-major), got {0}")]
    Count(usize),
    /// The last row is not 0 0 0 1.
    #[error("the last row of the registration matrix is {0:?}, not [0, 0, 0, 1]")]
    LastRow([f64; 4]),
    /// The matrix is not a rigid transform.
    #[error("the registration matrix is not a rigid transform: {0}")]
    NotRigid(PoseError),
    /// The file cannot be read.
    #[error("cannot read registration file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The error.
        source: std::io::Error,
    },
    /// The TOML is not a registration.
    #[error("registration file {path}: {source}")]
    Toml {
        /// The file (or `<string>`).
        path: String,
        /// The parse error.
        source: toml::de::Error,
    },
    /// A number that is not a number.
    #[error("registration number {index} ({text:?}) is not a number")]
    Number {
        /// 0-based position.
        index: usize,
        /// The text.
        text: String,
    },
}

/// The TOML form of a registration.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RegistrationFile {
    /// Row-major 4x4, rotation block unitless, translation column in millimetres.
    image_to_base_mm: [[f64; 4]; 4],
}

/// A fixed rigid transform from the client frame (an image or Slicer's RAS) to the robot
/// base frame {0}: `p_base = R p_client + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Registration {
    client_to_base: PoseSi,
}

impl Default for Registration {
    fn default() -> Self {
        Registration::identity()
    }
}

impl Registration {
    /// No registration: the client frame is {0}.
    pub fn identity() -> Self {
        Registration {
            client_to_base: Pose {
                t: Vector3::zeros(),
                r: Rotation3::identity(),
            },
        }
    }

    /// From a transform in SI units.
    pub fn from_pose(client_to_base: PoseSi) -> Self {
        Registration { client_to_base }
    }

    /// The transform client → base, SI.
    pub fn client_to_base(&self) -> &PoseSi {
        &self.client_to_base
    }

    /// From a row-major 4x4 matrix, translation in millimetres.
    pub fn from_matrix_mm(rows: &[[f64; 4]; 4]) -> Result<Self, RegistrationError> {
        if rows[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(RegistrationError::LastRow(rows[3]));
        }
        let m = Matrix3::from_fn(|i, j| rows[i][j]);
        let t = Vector3::from_fn(|i, _| rows[i][3]);
        if t.iter().any(|v| !v.is_finite()) {
            return Err(RegistrationError::NotRigid(PoseError::NonFinite {
                field: "translation",
            }));
        }
        let r = rotation_from_block(&m, "rotation").map_err(RegistrationError::NotRigid)?;
        Ok(Registration {
            client_to_base: Pose { t: t / MM_PER_M, r },
        })
    }

    /// From 16 numbers, row-major, translation in millimetres (a command-line argument).
    pub fn from_numbers_mm(numbers: &[f64]) -> Result<Self, RegistrationError> {
        if numbers.len() != 16 {
            return Err(RegistrationError::Count(numbers.len()));
        }
        let rows: [[f64; 4]; 4] = [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| numbers[4 * i + j]));
        Registration::from_matrix_mm(&rows)
    }

    /// From 16 numbers separated by commas and/or whitespace.
    pub fn parse_numbers_mm(text: &str) -> Result<Self, RegistrationError> {
        let numbers = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .enumerate()
            .map(|(index, s)| {
                s.parse::<f64>().map_err(|_| RegistrationError::Number {
                    index,
                    text: s.to_owned(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Registration::from_numbers_mm(&numbers)
    }

    /// From TOML text with the key `image_to_base_mm` (see the crate README).
    pub fn from_toml_str(text: &str, path: &str) -> Result<Self, RegistrationError> {
        let file: RegistrationFile =
            toml::from_str(text).map_err(|source| RegistrationError::Toml {
                path: path.to_owned(),
                source,
            })?;
        Registration::from_matrix_mm(&file.image_to_base_mm)
    }

    /// From a TOML file.
    pub fn load(path: &Path) -> Result<Self, RegistrationError> {
        let text = std::fs::read_to_string(path).map_err(|source| RegistrationError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Registration::from_toml_str(&text, &path.display().to_string())
    }

    /// A point in the client frame, in {0}.
    pub fn point_to_base(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.client_to_base.r * p + self.client_to_base.t
    }

    /// An orientation relative to the client frame, relative to {0}.
    pub fn rotation_to_base(&self, r: &Rotation3<f64>) -> Rotation3<f64> {
        self.client_to_base.r * r
    }

    /// A pose in the client frame, in {0}.
    pub fn pose_to_base(&self, pose: &PoseSi) -> PoseSi {
        Pose {
            t: self.point_to_base(&pose.t),
            r: self.rotation_to_base(&pose.r),
        }
    }

    /// A pose in {0}, in the client frame.
    pub fn pose_to_client(&self, pose: &PoseSi) -> PoseSi {
        let rt = self.client_to_base.r.inverse();
        Pose {
            t: rt * (pose.t - self.client_to_base.t),
            r: rt * pose.r,
        }
    }
}
