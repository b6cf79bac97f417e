//! The unit boundary: SI inside, millimetres and degrees at the edge (CONVENTIONS.md,
//! "Units"), and the number formats of the CSV and report output.

/// Millimetres to metres. Divides by 1000 so that e.g. 20 mm gives exactly the literal
/// 0.020 m the core's reference geometries use.
pub fn mm_to_m(mm: f64) -> f64 {
    mm / 1000.0
}

/// Metres to millimetres.
pub fn m_to_mm(m: f64) -> f64 {
    m * 1000.0
}

/// Degrees to radians.
pub fn deg_to_rad(deg: f64) -> f64 {
    deg.to_radians()
}

/// Radians to degrees.
pub fn rad_to_deg(rad: f64) -> f64 {
    rad.to_degrees()
}

/// Wraps an angle in degrees to (-180, 180].
pub fn wrap_deg(deg: f64) -> f64 {
    let w = deg - 360.0 * ((deg + 180.0) / 360.0).floor();
    if w <= -180.0 {
        w + 360.0
    } else {
        w
    }
}

/// Drops the sign of a formatted number that rounded to zero ("-0.000" -> "0.000").
fn unsigned_zero(s: String) -> String {
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => s,
    }
}

/// A length in mm or an angle in degrees for the CSV output: nine decimals, i.e. 1e-9 mm
/// or 1e-9 deg, better than 1e-9 relative for everything the robot measures in whole mm.
pub fn fixed9(x: f64) -> String {
    fixed(x, 9)
}

/// A number with `decimals` decimals, without the sign of a value that rounds to zero.
pub fn fixed(x: f64, decimals: usize) -> String {
    unsigned_zero(format!("{x:.decimals$}"))
}

/// An SI value of any magnitude (Jacobian entries, forces, condition numbers): a plain
/// decimal (no exponent) with ten significant digits, at most 20 decimals.
pub fn significant(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return if x.is_finite() {
            "0".to_string()
        } else {
            format!("{x}")
        };
    }
    let magnitude = x.abs().log10().floor();
    // Ten significant digits: digits after the point = 9 - exponent, clamped to 0..=20.
    let decimals = (9.0 - magnitude).clamp(0.0, 20.0) as usize;
    unsigned_zero(format!("{x:.decimals$}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_lands_in_half_open_interval() {
        assert_eq!(wrap_deg(180.0), 180.0);
        assert_eq!(wrap_deg(-180.0), 180.0);
        assert_eq!(wrap_deg(190.0), -170.0);
        assert_eq!(wrap_deg(-190.0), 170.0);
        assert_eq!(wrap_deg(45.0), 45.0);
    }

    #[test]
    fn formats_keep_ten_significant_digits() {
        assert_eq!(significant(0.05), "0.05000000000");
        assert_eq!(significant(-12.345678901234), "-12.34567890");
        assert_eq!(significant(1234.5), "1234.500000");
        assert_eq!(significant(0.0), "0");
        assert_eq!(fixed9(-1e-12), "0.000000000");
        assert_eq!(fixed9(170.88), "170.880000000");
    }

    #[test]
    fn millimetres_convert_to_the_core_literals() {
        assert_eq!(mm_to_m(20.0), 0.020);
        assert_eq!(mm_to_m(90.0), 0.090);
        assert_eq!(mm_to_m(160.0), 0.160);
        assert_eq!(mm_to_m(30.0), 0.030);
    }
}
