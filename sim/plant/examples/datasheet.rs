//! Prints the derived figures of the shipped plant: resolution, ratings, speeds, time
//! constants. `cargo run --example datasheet`
#![allow(clippy::needless_range_loop)] // indexing the six joints reads best
use plant::{Plant, PlantConfig, JOINT_NAMES, NUM_JOINTS};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let plant = Plant::new(&PlantConfig::default())?;
    let cpu = plant.counts_per_joint_unit();
    let rated = plant.rated_efforts();
    let speed = plant.no_load_speeds();
    for j in 0..NUM_JOINTS {
        let m = plant.joint(j)?.model();
        let r = m.circuit_resistance();
        let (unit, scale, eff) = if j < 3 {
            ("mm", 1e3, "N")
        } else {
            ("deg", 1f64.to_degrees(), "N m")
        };
        println!(
            "{:>6}: {:.4} {unit}/count, {:.3} {unit}/motor rev, rated {:.3} {eff}, \
             no-load {:.1} {unit}/s, stall {:.1} A, L/R {:.0} us, backlash {:.4} {unit}, \
             reflected motor inertia {:.3e}, back-drive eff. {:.2}",
            JOINT_NAMES[j],
            scale / cpu[j],
            scale * m.transmission.joint_travel_per_motor_rev(),
            rated[j],
            scale * speed[j],
            m.bridge.supply / r,
            1e6 * m.motor.electrical_time_constant(r),
            scale * m.backlash.width,
            m.reflected_motor_inertia(),
            m.transmission.backdrive_efficiency(),
        );
    }
    Ok(())
}
