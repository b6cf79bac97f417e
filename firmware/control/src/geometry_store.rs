//! The calibrated geometry on the board: the checks a received record must pass,
//! the record's layout in flash, and the log of records in the reserved flash sector. The
//! targets supply the flash ([`GeometryFlash`]); this is the logic, tested on the host.
//!
//! **Checks** ([`check`]), in order, each refusal naming what failed: the CRC, the layout,
//! version 0 (reserved for "none"), every value finite, the nominal robot equal to the
//! board's, every value within what a calibration can move it from the symmetric robot
//! ([`Plausible`]), the geometry valid and assemblable on every branch
//! (`PerChainGeometry::new`), and the inverse kinematics of the central pose on the board's
//! branch.
//!
//! **Flash log.** The sector is a sequence of [`SLOT_LEN`]-byte slots, written in order
//! and never rewritten until the sector is erased: a slot holds [`MAGIC`], the record's
//! fields little-endian, and the record's CRC; an erased slot reads all 0xFF. At boot the
//! last valid slot is the stored geometry ([`load_latest`]); a store writes the next
//! erased slot, erasing the sector first when none is left, and reads it back
//! ([`store`]). A store cut by a reset leaves a slot that fails its CRC: the previous
//! record stays the valid one.

use kinematics_core::{
    inverse, Branch, ChainDimensions, GeometryError, Mechanism, PerChain, PerChainGeometry, Pose,
    Real, RsprGeometry,
};
use master_link::{GeometryRecord, GeometryRefusal, GEOMETRY_CHAIN_VALUES, GEOMETRY_LAYOUT};
use nalgebra::Vector3;

/// Bytes per flash slot (a record takes [`RECORD_BYTES`]).
pub const SLOT_LEN: usize = 256;
/// Bytes a record takes in its slot: magic, layout and padding, version, 52 values, CRC.
pub const RECORD_BYTES: usize = 4 + 4 + 4 + 4 * VALUES + 4;
/// "RSPG": the first word of a written slot.
pub const MAGIC: u32 = u32::from_le_bytes(*b"RSPG");
/// Values in a record: the nominal (4) and the chains.
pub const VALUES: usize = 4 + 3 * GEOMETRY_CHAIN_VALUES;
const _: () = assert!(RECORD_BYTES <= SLOT_LEN, "a record must fit its slot");

/// How far a calibration may move each value from the symmetric robot and still be
/// plausible: several times the manufacturing tolerances (±0.5 mm, ±0.5 deg, ±20 counts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plausible {
    /// Positions and lengths, m.
    pub length_m: f64,
    /// Axis directions (each component of the unit vector).
    pub axis: f64,
    /// Encoder zeros of the legs, m.
    pub leg_zero_m: f64,
    /// Encoder zeros of the links, rad.
    pub link_zero_rad: f64,
}

impl Default for Plausible {
    /// 3 mm, 0.05 (about 3 deg), 3 mm, 3 deg.
    fn default() -> Self {
        Plausible {
            length_m: 3e-3,
            axis: 0.05,
            leg_zero_m: 3e-3,
            link_zero_rad: 3f64.to_radians(),
        }
    }
}

fn f64_of<T: Real>(x: T) -> f64 {
    x.to_subset().unwrap_or(f64::NAN)
}

fn lit<T: Real>(x: f32) -> T {
    nalgebra::convert(f64::from(x))
}

/// The values of one chain in record order.
fn chain_values<T: Real>(d: &ChainDimensions<T>) -> [f32; GEOMETRY_CHAIN_VALUES] {
    let f = |x: T| f64_of(x) as f32;
    let v = |x: &Vector3<T>| [f(x.x), f(x.y), f(x.z)];
    let [a, b, c] = v(&d.base_pivot);
    let [e, g, h] = v(&d.base_axis);
    let [i, j, k] = v(&d.platform_joint);
    let [l, m, n] = v(&d.platform_axis);
    [
        a,
        b,
        c,
        e,
        g,
        h,
        f(d.link_length),
        i,
        j,
        k,
        l,
        m,
        n,
        f(d.leg_offset),
        f(d.leg_zero),
        f(d.link_zero),
    ]
}

/// The record of a geometry (sealed with its CRC): what the host sends.
pub fn record_of<T: Real>(g: &PerChainGeometry<T>, version: u32) -> GeometryRecord {
    let n = g.nominal();
    let f = |x: T| f64_of(x) as f32;
    let c = g.chains();
    GeometryRecord {
        layout: GEOMETRY_LAYOUT,
        version,
        nominal: [f(n.e), f(n.rb), f(n.rp), f(n.hc)],
        chains: [
            chain_values(&c[kinematics_core::Chain::One]),
            chain_values(&c[kinematics_core::Chain::Two]),
            chain_values(&c[kinematics_core::Chain::Three]),
        ],
        crc: 0,
    }
    .sealed()
}

fn dims_of<T: Real>(v: &[f32; GEOMETRY_CHAIN_VALUES]) -> ChainDimensions<T> {
    let x = |k: usize| lit::<T>(v.get(k).copied().unwrap_or(f32::NAN));
    let v3 = |k: usize| Vector3::new(x(k), x(k + 1), x(k + 2));
    ChainDimensions {
        base_pivot: v3(0),
        base_axis: v3(3),
        link_length: x(6),
        platform_joint: v3(7),
        platform_axis: v3(10),
        leg_offset: x(13),
        leg_zero: x(14),
        link_zero: x(15),
    }
}

/// Checks a received record against the board's nominal robot and returns the geometry
/// it describes, or why not (see the module documentation).
pub fn check<T: Real>(
    rec: &GeometryRecord,
    nominal: &RsprGeometry<T>,
    branch: Branch,
    plausible: &Plausible,
) -> Result<PerChainGeometry<T>, GeometryRefusal> {
    if !rec.crc_ok() {
        return Err(GeometryRefusal::Crc);
    }
    if rec.layout != GEOMETRY_LAYOUT {
        return Err(GeometryRefusal::Layout { found: rec.layout });
    }
    if rec.version == 0 {
        return Err(GeometryRefusal::Version);
    }
    let values = rec.nominal.iter().chain(rec.chains.iter().flatten());
    if let Some(k) = values.clone().position(|v| !v.is_finite()) {
        return Err(GeometryRefusal::NonFinite { index: k as u8 });
    }
    let board = [nominal.e, nominal.rb, nominal.rp, nominal.hc];
    for (k, (got, want)) in rec.nominal.iter().zip(board).enumerate() {
        let want = f64_of(want);
        if (f64::from(*got) - want).abs() > 1e-6 * want.abs().max(1e-3) {
            return Err(GeometryRefusal::Nominal { index: k as u8 });
        }
    }
    let symmetric = PerChainGeometry::from(*nominal);
    for (c, values) in rec.chains.iter().enumerate() {
        let Some(chain) = kinematics_core::Chain::from_index(c) else {
            continue;
        };
        let reference = chain_values(&symmetric.chains()[chain]);
        for (k, (got, want)) in values.iter().zip(reference.iter()).enumerate() {
            let limit = match k {
                3..=5 | 10..=12 => plausible.axis,
                14 => plausible.leg_zero_m,
                15 => plausible.link_zero_rad,
                _ => plausible.length_m,
            };
            if (f64::from(*got) - f64::from(*want)).abs() > limit {
                return Err(GeometryRefusal::OutOfTolerance {
                    index: (4 + c * GEOMETRY_CHAIN_VALUES + k) as u8,
                });
            }
        }
    }
    let chains = PerChain(rec.chains.map(|v| dims_of::<T>(&v)));
    let g = PerChainGeometry::new(*nominal, chains).map_err(|e| match e {
        GeometryError::NotAssemblable { .. }
        | GeometryError::NonFinite { .. }
        | GeometryError::NotPositive { .. }
        | GeometryError::NotUnit { .. }
        | GeometryError::AxisOutOfRange { .. } => GeometryRefusal::NotAssemblable,
    })?;
    inverse(&g, &Pose::central(g.hc()), branch).map_err(|_| GeometryRefusal::CentralPose)?;
    Ok(g)
}

/// The slot bytes of a record.
pub fn encode_slot(rec: &GeometryRecord) -> [u8; SLOT_LEN] {
    let mut out = [0xFFu8; SLOT_LEN];
    let words = [MAGIC, u32::from(rec.layout), rec.version]
        .into_iter()
        .chain(
            rec.nominal
                .iter()
                .chain(rec.chains.iter().flatten())
                .map(|v| v.to_bits()),
        )
        .chain([rec.crc]);
    for (chunk, w) in out.chunks_exact_mut(4).zip(words) {
        chunk.copy_from_slice(&w.to_le_bytes());
    }
    out
}

/// The record in slot bytes: None for an erased slot, a torn write or another content
/// (magic or CRC wrong).
pub fn decode_slot(bytes: &[u8; SLOT_LEN]) -> Option<GeometryRecord> {
    let mut words = bytes
        .chunks_exact(4)
        .map(|c| <[u8; 4]>::try_from(c).map_or(0, u32::from_le_bytes));
    if words.next()? != MAGIC {
        return None;
    }
    let layout = u8::try_from(words.next()?).ok()?;
    let version = words.next()?;
    let mut nominal = [0f32; 4];
    for v in nominal.iter_mut() {
        *v = f32::from_bits(words.next()?);
    }
    let mut chains = [[0f32; GEOMETRY_CHAIN_VALUES]; 3];
    for v in chains.iter_mut().flatten() {
        *v = f32::from_bits(words.next()?);
    }
    let crc = words.next()?;
    let rec = GeometryRecord {
        layout,
        version,
        nominal,
        chains,
        crc,
    };
    rec.crc_ok().then_some(rec)
}

/// A flash failure reported by the target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// The driver refused or failed the operation.
    Driver,
    /// What was written does not read back.
    Verify,
}

/// The reserved flash sector, in slots (the target's driver).
pub trait GeometryFlash {
    /// Slots in the sector.
    fn slots(&self) -> usize;
    /// Reads slot `i`.
    fn read_slot(&mut self, i: usize, out: &mut [u8; SLOT_LEN]) -> Result<(), FlashError>;
    /// Programs slot `i` (erased before).
    fn write_slot(&mut self, i: usize, bytes: &[u8; SLOT_LEN]) -> Result<(), FlashError>;
    /// Erases the whole sector (every byte 0xFF).
    fn erase(&mut self) -> Result<(), FlashError>;
}

fn erased(bytes: &[u8; SLOT_LEN]) -> bool {
    bytes.iter().all(|b| *b == 0xFF)
}

/// The stored record: the last valid slot, with its index.
pub fn load_latest<F: GeometryFlash>(
    flash: &mut F,
) -> Result<Option<(usize, GeometryRecord)>, FlashError> {
    let mut buf = [0u8; SLOT_LEN];
    let mut latest = None;
    for i in 0..flash.slots() {
        flash.read_slot(i, &mut buf)?;
        if erased(&buf) {
            break;
        }
        if let Some(rec) = decode_slot(&buf) {
            latest = Some((i, rec));
        }
    }
    Ok(latest)
}

/// What a store did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stored {
    /// The slot written.
    pub slot: usize,
    /// The sector was erased first (the long operation: about 1 to 2 s on the STM32F405's
    /// 128 KB sector).
    pub erased: bool,
}

/// Writes `rec` into the next erased slot (erasing the sector when none is left) and reads
/// it back.
pub fn store<F: GeometryFlash>(flash: &mut F, rec: &GeometryRecord) -> Result<Stored, FlashError> {
    let mut buf = [0u8; SLOT_LEN];
    let mut free = None;
    for i in 0..flash.slots() {
        flash.read_slot(i, &mut buf)?;
        if erased(&buf) {
            free = Some(i);
            break;
        }
    }
    let erased_first = free.is_none();
    let slot = match free {
        Some(i) => i,
        None => {
            flash.erase()?;
            0
        }
    };
    let bytes = encode_slot(rec);
    flash.write_slot(slot, &bytes)?;
    flash.read_slot(slot, &mut buf)?;
    if decode_slot(&buf) != Some(*rec) {
        return Err(FlashError::Verify);
    }
    Ok(Stored {
        slot,
        erased: erased_first,
    })
}
