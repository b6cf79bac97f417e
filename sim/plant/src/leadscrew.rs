//! Lead screw: converts screw rotation into leg travel.

use std::f64::consts::TAU;

/// A lead screw with its nut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeadScrew {
    /// Travel per screw revolution, m.
    pub lead: f64,
    /// Efficiency when the screw drives the load (forward), 0..1.
    pub efficiency: f64,
}

impl LeadScrew {
    /// Screw angle per unit of travel, rad/m.
    pub fn rad_per_metre(&self) -> f64 {
        TAU / self.lead
    }

    /// Forward efficiency of a screw from its geometry: `tan(l) / tan(l + phi)` with the
    /// lead angle `l = atan(lead / (pi d_mean))` and the friction angle
    /// `phi = atan(mu / cos(half thread angle))`.
    pub fn efficiency_from_geometry(
        lead: f64,
        mean_diameter: f64,
        mu: f64,
        half_thread_angle: f64,
    ) -> f64 {
        let lambda = (lead / (std::f64::consts::PI * mean_diameter)).atan();
        let phi = (mu / half_thread_angle.cos()).atan();
        lambda.tan() / (lambda + phi).tan()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_screw_efficiency_follows_from_its_geometry() {
        // 6 mm lead, 7 mm mean diameter, PTFE on acetal mu = 0.10, ACME 29 deg thread.
        let eta = LeadScrew::efficiency_from_geometry(6e-3, 7e-3, 0.10, 14.5f64.to_radians());
        assert!((eta - 0.70).abs() < 0.01, "{eta}");
    }
}
