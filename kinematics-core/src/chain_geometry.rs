//! The RSPR robot with a geometry of its own for each chain: what a calibration
//! identifies. The symmetric robot of four numbers ([`RsprGeometry`]) is one instance of it
//! (`From<RsprGeometry>`); IK, the Jacobians, FK, the statics and the guards work on it
//! unchanged, since it implements [`Mechanism`].
//!
//! **The model of chain i** (every vector in SI; base quantities in {0}, platform ones in
//! {p}):
//! - the rotating link turns about the unit axis a_i through the base pivot c_i; the
//!   spherical-joint centre b_i lies on the circle of radius rb_i (the link length) about
//!   a_i, in the plane through c_i normal to a_i:
//!   b_i = c_i + rb_i (cos φ_i ρ_i + sin φ_i (a_i × ρ_i)), where ρ_i is the chain's radial
//!   direction [cos ξ_i, sin ξ_i, 0] made normal to a_i (so φ_i is θ_i of CONVENTIONS.md
//!   when a_i = z0);
//! - the upper revolute joint is centred at pp_i with the unit axis r_i (in {p}); the leg
//!   runs from b_i to p_i = t + R pp_i in the plane through p_i normal to R r_i;
//! - the joints the encoders report: the leg
//!   l_i = |p_i − b_i| − leg_offset_i − leg_zero_i and the link angle
//!   θ_i = wrap(φ_i − link_zero_i). `leg_offset_i` is the leg's length offset (its fixed
//!   parts differ from the drawing), `leg_zero_i` and `link_zero_i` the encoders' zero
//!   offsets (where homing puts the count's zero); the leg's two offsets enter only as their
//!   sum, so a calibration determines that sum.
//!
//! With a_i = z0, c_i = e [cos ξ_i, sin ξ_i, 0], rb_i = rb, pp_i = rp [cos ξ_i, sin ξ_i, 0],
//! r_i = z0 × ρ_i and zero offsets, this is the thesis's RSPR (Eq. 6.1-6.22).
//!
//! **The inverse kinematics of a chain** is the thesis's construction (Eq. 6.13-6.22)
//! with the base plane replaced by the plane of the link's circle: the leg plane meets it
//! in a line v_i (direction a_i × R r_i, pointing along the projection of R pp_i as in
//! Eq. 6.18), and b_i is where that line meets the circle; the larger root along v_i is the
//! "outer" branch (bit clear), as in CONVENTIONS.md. The serial block (Eq. 7.19-7.21) uses
//! ŝn_i = a_i: the spherical joint moves along a_i × (b_i − c_i) per unit link rate.
//!
//! The singularity and tilt measures use the nominal rp and rb as their scales
//! ([`PerChainGeometry::nominal`]), and the tilt's link frame is built about z0 as on the
//! symmetric robot ([`crate::tilt`]): with axes within a degree of z0 the tilt differs
//! from the physical ball-in-socket angle by less than that degree.

use crate::chain::{Chain, PerChain};
use crate::geometry::{check_central, GeometryError, RsprGeometry};
use crate::mechanism::SerialBlock;
use crate::mechanism::{radial, ChainSolution, IkFailure, JointKind, Mechanism, PlatformChain};
use crate::pose::Pose;
use crate::scalar::{axpy3, cross3, dot3, lit, norm3, sqrt, sub3, to_f64, wrap_angle, Real};
use nalgebra::Vector3;

/// The dimensions of one chain (see the module documentation for the model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainDimensions<T: Real> {
    /// Base pivot c_i: where the rotating link's axis meets the plane of its circle (m, {0}).
    pub base_pivot: Vector3<T>,
    /// Unit axis a_i of the rotating link ({0}); +z0 on the drawing.
    pub base_axis: Vector3<T>,
    /// Link length rb_i: the radius of the spherical joint's circle about a_i (m).
    pub link_length: T,
    /// Centre pp_i of the upper revolute joint (m, {p}).
    pub platform_joint: Vector3<T>,
    /// Unit axis r_i of the upper revolute joint ({p}).
    pub platform_axis: Vector3<T>,
    /// The leg's length offset (m): |p_i − b_i| = l_i + leg_offset + leg_zero.
    pub leg_offset: T,
    /// The leg encoder's zero offset (m): enters as `leg_offset` does (only their sum is
    /// observable).
    pub leg_zero: T,
    /// The link encoder's zero offset (rad): θ_i = φ_i − link_zero.
    pub link_zero: T,
}

impl<T: Real> ChainDimensions<T> {
    /// Chain `chain` of the symmetric robot `g`.
    pub fn symmetric(g: &RsprGeometry<T>, chain: Chain) -> Self {
        let rad = radial::<T>(chain);
        ChainDimensions {
            base_pivot: Vector3::new(rad.x * g.e, rad.y * g.e, T::zero()),
            base_axis: Vector3::new(T::zero(), T::zero(), T::one()),
            link_length: g.rb,
            platform_joint: Vector3::new(rad.x * g.rp, rad.y * g.rp, T::zero()),
            platform_axis: Vector3::new(-rad.y, rad.x, T::zero()),
            leg_offset: T::zero(),
            leg_zero: T::zero(),
            link_zero: T::zero(),
        }
    }

    /// The same dimensions in another scalar (f64 on the host -> f32 on the board).
    pub fn cast<U: Real>(&self) -> ChainDimensions<U> {
        let s = |x: T| lit::<U>(to_f64(x));
        let v = |x: &Vector3<T>| x.map(s);
        ChainDimensions {
            base_pivot: v(&self.base_pivot),
            base_axis: v(&self.base_axis),
            link_length: s(self.link_length),
            platform_joint: v(&self.platform_joint),
            platform_axis: v(&self.platform_axis),
            leg_offset: s(self.leg_offset),
            leg_zero: s(self.leg_zero),
            link_zero: s(self.link_zero),
        }
    }
}

/// What each chain's inverse kinematics needs besides its dimensions, derived once.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Derived<T: Real> {
    /// ρ_i: the radial direction made normal to a_i (the zero of φ_i).
    zero_dir: Vector3<T>,
    /// a_i × ρ_i.
    quarter_dir: Vector3<T>,
    /// The horizontal direction of pp_i in {p} (orients v_i, Eq. 6.18).
    platform_radial: Vector3<T>,
}

/// An RSPR robot with per-chain dimensions and encoder zero offsets; implements
/// [`Mechanism`]. Built validated ([`PerChainGeometry::new`]) or from the symmetric robot
/// (`From<RsprGeometry>`).
#[derive(Copy, Debug, PartialEq)]
pub struct PerChainGeometry<T: Real> {
    nominal: RsprGeometry<T>,
    chains: PerChain<ChainDimensions<T>>,
    derived: PerChain<Derived<T>>,
}

// A copy of the whole value (the derived `Clone` of a generic type clones field by
// field, element by element: some 800 bytes of code wherever a mechanism is cloned).
impl<T: Real> Clone for PerChainGeometry<T> {
    fn clone(&self) -> Self {
        *self
    }
}

/// The names of the fields of each chain, for errors.
const FIELDS: [[&str; 8]; 3] = {
    macro_rules! names {
        ($c:literal) => {
            [
                concat!("chain ", $c, " base_pivot"),
                concat!("chain ", $c, " base_axis"),
                concat!("chain ", $c, " link_length"),
                concat!("chain ", $c, " platform_joint"),
                concat!("chain ", $c, " platform_axis"),
                concat!("chain ", $c, " leg_offset"),
                concat!("chain ", $c, " leg_zero"),
                concat!("chain ", $c, " link_zero"),
            ]
        };
    }
    [names!("1"), names!("2"), names!("3")]
};

fn field(chain: Chain, k: usize) -> &'static str {
    FIELDS
        .get(chain.index())
        .and_then(|f| f.get(k))
        .copied()
        .unwrap_or("chain")
}

/// Largest accepted |1 − |axis|| of an axis given as unit.
fn unit_tolerance<T: Real>() -> T {
    lit(1e-4)
}

fn derive<T: Real>(chain: Chain, d: &ChainDimensions<T>) -> Option<Derived<T>> {
    let rad = radial::<T>(chain);
    let a = d.base_axis;
    let along = dot3(&rad, &a);
    let rho = Vector3::new(
        rad.x - a.x * along,
        rad.y - a.y * along,
        rad.z - a.z * along,
    );
    let n = norm3(&rho);
    // With a_i within 60 deg of z0 (checked), |ρ_i| ≥ 0.5.
    if !(n > lit(0.25)) {
        return None;
    }
    let zero_dir = Vector3::new(rho.x / n, rho.y / n, rho.z / n);
    let quarter_dir = cross3(&a, &zero_dir);
    let pp = d.platform_joint;
    let h = sqrt(pp.x * pp.x + pp.y * pp.y);
    if !(h > T::default_epsilon()) {
        return None;
    }
    Some(Derived {
        zero_dir,
        quarter_dir,
        platform_radial: Vector3::new(pp.x / h, pp.y / h, T::zero()),
    })
}

/// Checks one chain's dimensions (see [`PerChainGeometry::new`]) and normalises its axes.
fn check_chain<T: Real>(chain: Chain, d: &mut ChainDimensions<T>) -> Result<(), GeometryError> {
    let vectors = [
        (0, d.base_pivot),
        (1, d.base_axis),
        (3, d.platform_joint),
        (4, d.platform_axis),
    ];
    for (k, v) in vectors {
        if !crate::scalar::all_finite(v.as_slice()) {
            return Err(GeometryError::NonFinite {
                field: field(chain, k),
            });
        }
    }
    for (k, v) in [
        (2, d.link_length),
        (5, d.leg_offset),
        (6, d.leg_zero),
        (7, d.link_zero),
    ] {
        if !v.is_finite() {
            return Err(GeometryError::NonFinite {
                field: field(chain, k),
            });
        }
    }
    if !(d.link_length > T::zero()) {
        return Err(GeometryError::NotPositive {
            field: field(chain, 2),
            value_m: to_f64(d.link_length),
        });
    }
    for k in [1, 4] {
        let v = if k == 1 {
            &mut d.base_axis
        } else {
            &mut d.platform_axis
        };
        let n = norm3(v);
        if !((n - T::one()).abs() <= unit_tolerance()) {
            return Err(GeometryError::NotUnit {
                field: field(chain, k),
                norm: to_f64(n),
            });
        }
        *v = Vector3::new(v.x / n, v.y / n, v.z / n);
    }
    if !(d.base_axis.z >= lit(0.5)) {
        return Err(GeometryError::AxisOutOfRange {
            field: field(chain, 1),
        });
    }
    let pp = d.platform_joint;
    let off_axis = sqrt(pp.x * pp.x + pp.y * pp.y);
    if !(off_axis > d.link_length * lit(1e-3)) {
        return Err(GeometryError::NotPositive {
            field: field(chain, 3),
            value_m: to_f64(off_axis),
        });
    }
    Ok(())
}

impl<T: Real> PerChainGeometry<T> {
    /// A validated geometry: every value finite, the axes unit vectors (to 1e-4; they are
    /// then normalised), the link lengths positive, the axes within 60 deg of z0 (the
    /// link's zero direction must be defined), the platform joints off the platform's axis,
    /// and the central configuration solvable on every branch. `nominal` is the drawing
    /// the chains deviate from: its rp, e, hc and rb are the scales of the measures and the
    /// central pose ([`Mechanism::hc`]).
    pub fn new(
        nominal: RsprGeometry<T>,
        chains: PerChain<ChainDimensions<T>>,
    ) -> Result<Self, GeometryError> {
        let mut chains = chains;
        for chain in Chain::ALL {
            check_chain(chain, &mut chains[chain])?;
        }
        let derived = PerChain::try_from_fn(|c| {
            derive(c, &chains[c]).ok_or(GeometryError::AxisOutOfRange { field: field(c, 1) })
        })?;
        let g = PerChainGeometry {
            nominal,
            chains,
            derived,
        };
        check_central(&g)?;
        Ok(g)
    }

    /// The drawing the chains deviate from (the scales of the measures, the central pose).
    pub fn nominal(&self) -> &RsprGeometry<T> {
        &self.nominal
    }

    /// The dimensions of the three chains (axes normalised).
    pub fn chains(&self) -> &PerChain<ChainDimensions<T>> {
        &self.chains
    }

    /// The same geometry in another scalar (f64 on the host -> f32 on the board),
    /// validated again in that scalar.
    pub fn cast<U: Real>(&self) -> Result<PerChainGeometry<U>, GeometryError> {
        let n = &self.nominal;
        let s = |x: T| lit::<U>(to_f64(x));
        let nominal = RsprGeometry {
            e: s(n.e),
            rb: s(n.rb),
            rp: s(n.rp),
            hc: s(n.hc),
        };
        PerChainGeometry::new(nominal, self.chains.map(|_, d| d.cast()))
    }
}

impl<T: Real> From<RsprGeometry<T>> for PerChainGeometry<T> {
    /// The symmetric robot as a per-chain geometry: the same kinematics to rounding.
    fn from(g: RsprGeometry<T>) -> Self {
        let chains = PerChain::from_fn(|c| ChainDimensions::symmetric(&g, c));
        let derived = PerChain::from_fn(|c| {
            let rad = radial::<T>(c);
            let z = Vector3::new(T::zero(), T::zero(), T::one());
            Derived {
                zero_dir: rad,
                quarter_dir: cross3(&z, &rad),
                platform_radial: rad,
            }
        });
        PerChainGeometry {
            nominal: g,
            chains,
            derived,
        }
    }
}

impl<T: Real> Mechanism<T> for PerChainGeometry<T> {
    fn rp(&self) -> T {
        self.nominal.rp
    }
    fn e(&self) -> T {
        self.nominal.e
    }
    fn hc(&self) -> T {
        self.nominal.hc
    }
    fn joint_kinds(&self) -> [JointKind; 6] {
        use JointKind::*;
        [Linear, Linear, Linear, Angular, Angular, Angular]
    }
    fn length_scale(&self) -> T {
        self.nominal.rb
    }

    #[inline]
    fn platform_chain(&self, pose: &Pose<T>, chain: Chain) -> PlatformChain<T> {
        let d = &self.chains[chain];
        let x = &self.derived[chain];
        let r = pose.r.matrix();
        // R·v written out (see mechanism::symmetric_platform_chain).
        let rot = |v: &Vector3<T>| {
            Vector3::new(
                r.m11 * v.x + r.m12 * v.y + r.m13 * v.z,
                r.m21 * v.x + r.m22 * v.y + r.m23 * v.z,
                r.m31 * v.x + r.m32 * v.y + r.m33 * v.z,
            )
        };
        PlatformChain {
            p: crate::scalar::add3(&pose.t, &rot(&d.platform_joint)),
            u: rot(&x.platform_radial),
            m: rot(&d.platform_axis),
            n: Vector3::new(r.m13, r.m23, r.m33),
            e: d.base_pivot,
            radial: x.zero_dir,
        }
    }

    #[inline]
    fn chain_ik(
        &self,
        chain: Chain,
        pc: &PlatformChain<T>,
        inner: bool,
        out: &mut ChainSolution<T>,
    ) -> Result<(), IkFailure> {
        let d = &self.chains[chain];
        let x = &self.derived[chain];
        let eps = T::default_epsilon() * lit(64.0);
        let a = d.base_axis;
        let c = d.base_pivot;
        // The leg plane (through p_i, normal m) meets the circle's plane (through c_i,
        // normal a_i) in the line v_i (Eq. 6.13-6.17 with the base plane generalised).
        let v_raw = cross3(&a, &pc.m);
        let v_len = norm3(&v_raw);
        if !(v_len > eps) {
            return Err(IkFailure::DegeneratePlane);
        }
        let mut v = Vector3::new(v_raw.x / v_len, v_raw.y / v_len, v_raw.z / v_len);
        // Eq. 6.18: v_i points along the projection of R pp_i.
        if dot3(&v, &pc.u) < T::zero() {
            v = -v;
        }
        // A point d_i of that line: from p_i along g = m × v (in the leg plane, normal to
        // v_i) to the circle's plane (Eq. 6.8-6.10).
        let g = cross3(&pc.m, &v);
        let ga = dot3(&g, &a);
        if !(ga.abs() > eps) {
            return Err(IkFailure::DegeneratePlane);
        }
        let k = dot3(&sub3(&c, &pc.p), &a) / ga;
        let dpt = axpy3(&pc.p, &g, k);
        // Eq. 6.19-6.22: |d + t v − c|² = rb² with |v| = 1.
        let dc = sub3(&dpt, &c);
        let h = dot3(&dc, &v);
        let cc = dot3(&dc, &dc) - d.link_length * d.link_length;
        let disc = h * h - cc;
        if !(disc >= T::zero()) {
            return Err(IkFailure::NoRealRoot);
        }
        let root = sqrt(disc);
        let t = if inner { -h - root } else { -h + root };
        let b = axpy3(&dpt, &v, t);
        let lb = sub3(&b, &c);
        let s1_vec = sub3(&pc.p, &b);
        let leg = norm3(&s1_vec);
        if !(leg > eps * d.link_length) {
            return Err(IkFailure::ZeroLengthLeg);
        }
        let phi = dot3(&lb, &x.quarter_dir).atan2(dot3(&lb, &x.zero_dir));
        *out = ChainSolution {
            e: c,
            b,
            p: pc.p,
            lb,
            s1: Vector3::new(s1_vec.x / leg, s1_vec.y / leg, s1_vec.z / leg),
            leg,
            s2: pc.m,
            axis: a,
            qa: leg - d.leg_offset - d.leg_zero,
            qb: wrap_angle(phi - d.link_zero),
            gamma: T::zero(),
        };
        Ok(())
    }

    fn serial_block(&self, s: &ChainSolution<T>) -> SerialBlock<T> {
        // Eq. 7.19-7.21 with ŝn = a_i: b_i moves along a_i × l_b per unit link rate.
        let tip = cross3(&s.axis, &s.lb);
        SerialBlock {
            a11: T::one(),
            a12: dot3(&s.s1, &tip),
            a21: T::zero(),
            a22: dot3(&s.s2, &tip),
        }
    }

    fn serial_measure(&self, s: &ChainSolution<T>) -> (T, T) {
        // Eq. 10.6, over the nominal link length.
        let cn2 = self.serial_block(s).a22.abs();
        (cn2, cn2 / self.nominal.rb)
    }
}
