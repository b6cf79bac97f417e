use kinematics_core::*;
use nalgebra::{Rotation3, Vector3, Vector6};
fn main() {
    let g = RsprGeometry::<f64>::reference();
    let axes = SocketAxes::new(&g).unwrap();
    let axis = Vector3::new(1.0, 1.0, 0.0).normalize();
    let se = Vector6::new(7.0, 7.0, 7.0, 0.7, 0.7, 0.7);
    for (name, rv) in [("parallel", Vector3::zeros()), ("rot20", axis * 20f64.to_radians())] {
        let (mut lmin, mut lmax, mut thmin, mut thmax, mut tilt, mut pierce, mut ser, mut par) = (1e9f64, -1e9f64, 1e9f64, -1e9f64, 0f64, 1e9f64, 1e9f64, 1e9f64);
        let (mut fmax, mut tmax) = (0f64, 0f64);
        for i in 0..=20 { for j in 0..=20 { for k in 0..=10 {
            let t = Vector3::new(-0.02 + 0.002 * i as f64, -0.02 + 0.002 * j as f64, 0.15 + 0.002 * k as f64);
            let pose = Pose { t, r: Rotation3::from_scaled_axis(rv) };
            let s = inverse(&g, &pose, Branch::OUTER).unwrap();
            let q = s.q();
            for c in 0..3 { lmin = lmin.min(q[c]); lmax = lmax.max(q[c]); thmin = thmin.min(q[c+3]); thmax = thmax.max(q[c+3]); }
            for (_, t) in tilt_angles(&s, &axes).iter() { tilt = tilt.max(*t); }
            for (_, c) in s.chains.iter() { let h = 0.06; let p = c.b + c.s1 * ((h - c.b.z) / c.s1.z); pierce = pierce.min(p.xy().norm()); }
            let m = measures(&g, &s).unwrap();
            for (_, r) in m.serial_relative.iter() { ser = ser.min(*r); }
            par = par.min(m.parallel_inv_cond);
            let jac = jacobian(&g, &s).unwrap();
            let st = actuator_forces(&jac, g.rp, &se, 1e-6).unwrap();
            for c in 0..3 { fmax = fmax.max(st.tau[c].abs()); tmax = tmax.max(st.tau[c+3].abs()); }
        }}}
        println!("{name}: l {:.2}..{:.2} mm, theta {:.2}..{:.2} deg, tilt max {:.2} deg, pierce(60mm) min {:.2} mm, serial rel min {:.3}, inv_cond min {:.4}, |f| max {:.2} N, |t| max {:.3} Nm",
            lmin*1e3, lmax*1e3, thmin.to_degrees(), thmax.to_degrees(), tilt.to_degrees(), pierce*1e3, ser, par, fmax, tmax);
    }
}
