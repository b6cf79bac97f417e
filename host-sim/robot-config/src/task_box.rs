//! The thesis's task (CONVENTIONS.md, "The reference robot"): every point of a box centred
//! at [0, 0, hc], with the platform parallel to the base and rotated by a fixed angle about
//! [1,1,0]/sqrt(2). One grid generator for every tool that sweeps the task (`report`,
//! `check --task-box`, `ranges`, `workspace`, `synth`).

use thiserror::Error;

/// The thesis's box edge lengths, mm.
pub const THESIS_BOX_MM: [f64; 3] = [40.0, 40.0, 20.0];
/// The thesis's rotation of the second orientation about [1,1,0]/sqrt(2), deg.
pub const THESIS_TILT_DEG: f64 = 20.0;

/// The task box and its sampling.
#[derive(Clone, Debug, PartialEq)]
pub struct TaskBox {
    /// Grid points along x, y, z (each >= 1).
    pub grid: [usize; 3],
    /// Box edge lengths, mm.
    pub box_mm: [f64; 3],
    /// Rotation of the second orientation about [1,1,0]/sqrt(2), deg.
    pub tilt_deg: f64,
}

/// One orientation of the task.
#[derive(Clone, Debug, PartialEq)]
pub struct Orientation {
    /// A short name for tables and CSV: `parallel` or `rotated`.
    pub key: &'static str,
    /// A name for people, e.g. `+20 deg about [1,1,0]/sqrt(2)`.
    pub label: String,
    /// The rotation vector (axis * angle), deg.
    pub rotation_deg: [f64; 3],
}

/// One grid point of the task.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TaskPose {
    /// x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
    pub pose: [f64; 6],
    /// Index into [`TaskBox::orientations`].
    pub orientation: usize,
}

/// A grid that is not whole numbers 1..=1000 per axis.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum TaskBoxError {
    #[error("{field}: {value} is not a whole number 1..=1000")]
    NotWholeGrid {
        /// Where the grid came from (a flag, a task file's key).
        field: String,
        /// The first bad value.
        value: f64,
    },
}

impl TaskBox {
    /// The thesis's box and orientations on a grid.
    pub fn thesis(grid: [usize; 3]) -> Self {
        TaskBox {
            grid,
            box_mm: THESIS_BOX_MM,
            tilt_deg: THESIS_TILT_DEG,
        }
    }

    /// A grid of whole numbers 1..=1000 from its values (given as numbers, e.g. a flag's or
    /// a TOML array's); `field` names them in the error.
    pub fn grid_from(field: &str, values: [f64; 3]) -> Result<[usize; 3], TaskBoxError> {
        let mut grid = [1usize; 3];
        for (g, &f) in grid.iter_mut().zip(values.iter()) {
            if !((1.0..=1000.0).contains(&f) && f.fract() == 0.0) {
                return Err(TaskBoxError::NotWholeGrid {
                    field: field.to_string(),
                    value: f,
                });
            }
            *g = f as usize;
        }
        Ok(grid)
    }

    /// The two orientations: parallel, and rotated by `tilt_deg` about [1,1,0]/sqrt(2).
    pub fn orientations(&self) -> [Orientation; 2] {
        let c = self.tilt_deg / std::f64::consts::SQRT_2;
        [
            Orientation {
                key: "parallel",
                label: "parallel".to_string(),
                rotation_deg: [0.0; 3],
            },
            Orientation {
                key: "rotated",
                label: format!("{:+} deg about [1,1,0]/sqrt(2)", self.tilt_deg),
                rotation_deg: [c, c, 0.0],
            },
        ]
    }

    /// The grid coordinates along one axis: `n` points spanning `length` around `centre`.
    fn axis(n: usize, length: f64, centre: f64) -> Vec<f64> {
        if n <= 1 {
            return vec![centre];
        }
        (0..n)
            .map(|i| centre - length / 2.0 + length * i as f64 / (n - 1) as f64)
            .collect()
    }

    /// Every task pose (mm, deg): the grid at each orientation, x fastest.
    pub fn poses(&self, hc_mm: f64) -> Vec<TaskPose> {
        let [nx, ny, nz] = self.grid;
        let [dx, dy, dz] = self.box_mm;
        let mut out = Vec::new();
        for (orientation, o) in self.orientations().iter().enumerate() {
            let [rx, ry, rz] = o.rotation_deg;
            for &z in &Self::axis(nz, dz, hc_mm) {
                for &y in &Self::axis(ny, dy, 0.0) {
                    for &x in &Self::axis(nx, dx, 0.0) {
                        out.push(TaskPose {
                            pose: [x, y, z, rx, ry, rz],
                            orientation,
                        });
                    }
                }
            }
        }
        out
    }

    /// `40 x 40 x 20 mm centred at (0, 0, 160.0) mm, 9 x 9 x 5 grid`.
    pub fn describe(&self, hc_mm: f64) -> String {
        let [nx, ny, nz] = self.grid;
        let [dx, dy, dz] = self.box_mm;
        format!("{dx} x {dy} x {dz} mm centred at (0, 0, {hc_mm:.1}) mm, {nx} x {ny} x {nz} grid")
    }
}

/// A pose for people: position in mm, rotation vector in deg.
pub fn pose_label(p: &[f64; 6]) -> String {
    let [x, y, z, rx, ry, rz] = p;
    format!("({x:.1}, {y:.1}, {z:.1}) mm, r ({rx:.2}, {ry:.2}, {rz:.2}) deg")
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn the_grid_spans_the_box_at_both_orientations() {
        let t = TaskBox::thesis([9, 9, 5]);
        let poses = t.poses(160.0);
        assert_eq!(poses.len(), 2 * 9 * 9 * 5);
        let first = poses.first().unwrap();
        assert_eq!(first.pose, [-20.0, -20.0, 150.0, 0.0, 0.0, 0.0]);
        let last = poses.last().unwrap();
        assert_eq!(last.orientation, 1);
        assert_eq!(&last.pose[..3], &[20.0, 20.0, 170.0]);
        // 20 deg about [1,1,0]/sqrt(2) as a rotation vector.
        let r = last.pose;
        assert!(((r[3] * r[3] + r[4] * r[4]).sqrt() - 20.0).abs() < 1e-12);
        assert_eq!(r[3], r[4]);
        assert_eq!(TaskBox::thesis([1, 1, 1]).poses(160.0).len(), 2);
    }

    #[test]
    fn grids_are_whole_numbers_1_to_1000() {
        assert_eq!(TaskBox::grid_from("g", [9.0, 9.0, 5.0]).unwrap(), [9, 9, 5]);
        assert_eq!(
            TaskBox::grid_from("g", [1.0, 1000.0, 1.0]).unwrap(),
            [1, 1000, 1]
        );
        for bad in [
            [0.0, 9.0, 5.0],
            [2.5, 9.0, 5.0],
            [9.0, 1001.0, 5.0],
            [9.0, 9.0, f64::NAN],
        ] {
            let e = TaskBox::grid_from("task.grid", bad).unwrap_err();
            assert!(
                e.to_string().starts_with("task.grid: ") && e.to_string().contains("whole number"),
                "{e}"
            );
        }
    }
}
