use board_profile::BoardProfile;
use identify::*;
use plant::PlantConfig;
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(30);
    let nominal = PlantConfig::shipped()?;
    let p = BoardProfile::REFERENCE;
    let mut worst = [0.0f64; 8];
    let mut fails = 0;
    for seed in 1..=n {
        let cfg = perturb::perturbed(&nominal, seed.wrapping_mul(0x9E3779B97F4A7C15), 0.3)?;
        for j in 0..6 {
            let rig = rig_of(&cfg, &p, j, true)?;
            let prior = Prior::from_model(rig_of(&nominal, &p, j, false)?.model());
            let t = Prior::from_model(rig.model());
            match identify_and_tune(&rig, &prior, &Settings::for_kind(rig.kind())) {
                Ok(r) => {
                    let id = &r.identified;
                    let e = [
                        (id.mass.value / t.mass - 1.0).abs(),
                        (id.coulomb.value / t.coulomb - 1.0).abs(),
                        (id.damping() / t.damping() - 1.0).abs(),
                        (id.force_per_amp.value / t.force_per_amp - 1.0).abs(),
                        if j < 3 {
                            (id.backlash.map_or(9.0, |b| b.value) / rig.model().backlash.width
                                - 1.0)
                                .abs()
                        } else {
                            0.0
                        },
                        ((r.measured.overshoot - r.predicted.overshoot) / r.predicted.overshoot)
                            .abs(),
                        ((r.measured.settling_time_s - r.predicted.settling_time_s)
                            / r.predicted.settling_time_s)
                            .abs(),
                        r.joint_excursion / r.excitation.travel_limit,
                    ];
                    for i in 0..8 {
                        if e[i] > worst[i] {
                            worst[i] = e[i];
                            if i >= 5 && e[i] > 0.15 {
                                println!(
                                    "seed {seed} j {j} q{i} {:.3} pred {:?} meas {:?}",
                                    e[i], r.predicted, r.measured
                                );
                            }
                        }
                    }
                }
                Err(e) => {
                    fails += 1;
                    println!("seed {seed} joint {j}: {e}");
                }
            }
        }
    }
    for j in [0, 3] {
        let rig = rig_of(&nominal, &p, j, true)?;
        let prior = Prior::from_model(rig.model());
        let r = identify_and_tune(&rig, &prior, &Settings::for_kind(rig.kind()))?;
        let bl = servo::BacklashConfig::<f64>::default().joints[j];
        let a = response::tracking(&rig, &reference_gains(rig.kind()), bl)?;
        let b = response::tracking(&rig, &r.tuning.gains, bl)?;
        println!(
            "nominal {}: tracking RMS {:.3e} with the reference gains, {:.3e} identified (x{:.3}); max {:.3e} vs {:.3e}",
            rig.name(), a.rms_load, b.rms_load, b.rms_load / a.rms_load, a.max_load, b.max_load
        );
    }
    println!("worst over {n} plants x 6 joints: M {:.1}% Fc {:.1}% B {:.1}% k {:.1}% backlash {:.1}% overshoot {:.1}% settling {:.1}% joint travel/limit {:.3}; failures {fails}",
        100.0*worst[0],100.0*worst[1],100.0*worst[2],100.0*worst[3],100.0*worst[4],100.0*worst[5],100.0*worst[6],worst[7]);
    Ok(())
}
