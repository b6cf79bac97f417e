//! Helpers shared by the integration tests.
#![allow(dead_code)]

use plant::{Plant, PlantConfig, NUM_JOINTS};

pub type TestResult = Result<(), Box<dyn std::error::Error>>;

/// A typical mid-stroke pose: legs at 170 mm, links at 0.
pub const HOME: [f64; NUM_JOINTS] = [0.170, 0.170, 0.170, 0.0, 0.0, 0.0];

/// The shipped plant at `HOME`.
pub fn plant() -> Result<Plant, Box<dyn std::error::Error>> {
    let mut p = Plant::new(&PlantConfig::default())?;
    p.set_joint_positions(HOME)?;
    Ok(p)
}

/// The shipped plant at `HOME` with the drivers' current regulation and overcurrent
/// protection out of the way: the motors and transmissions alone (data-sheet checks).
pub fn unregulated_plant() -> Result<Plant, Box<dyn std::error::Error>> {
    let mut cfg = PlantConfig::default();
    for p in cfg.prismatic.iter_mut() {
        p.drive.current_limit_a = 1000.0;
        p.drive.driver_ocp_a = 1000.0;
    }
    for r in cfg.rotary.iter_mut() {
        r.drive.current_limit_a = 1000.0;
        r.drive.driver_ocp_a = 1000.0;
    }
    let mut p = Plant::new(&cfg)?;
    p.set_joint_positions(HOME)?;
    Ok(p)
}

/// Extends the wrapping 16-bit counters to i64, as the controller must (valid while fewer
/// than 32768 counts pass between two reads).
#[derive(Debug, Clone)]
pub struct CounterExtender {
    last: [u16; NUM_JOINTS],
    pub total: [i64; NUM_JOINTS],
}

impl CounterExtender {
    pub fn new(p: &Plant) -> Self {
        CounterExtender {
            last: p.encoder_counts(),
            total: [0; NUM_JOINTS],
        }
    }

    pub fn update(&mut self, p: &Plant) -> [i64; NUM_JOINTS] {
        let now = p.encoder_counts();
        for j in 0..NUM_JOINTS {
            self.total[j] += i64::from(now[j].wrapping_sub(self.last[j]) as i16);
        }
        self.last = now;
        self.total
    }
}

/// |a - b| <= tol, with a readable failure.
pub fn assert_close(what: &str, a: f64, b: f64, tol: f64) {
    assert!(
        (a - b).abs() <= tol,
        "{what}: {a} vs {b} differ by {} > {tol}",
        (a - b).abs()
    );
}
