//! What the board records during an excitation, one sample per control tick.

/// One control tick: what the board read at the tick, and the duty it then applied until
/// the next tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// The duty applied from this tick to the next (as the PWM produced it), in [-1, 1].
    pub duty: f64,
    /// The motor current read at the tick, A.
    pub current_a: f64,
    /// The encoder count at the tick (extended to 64 bits).
    pub count: i64,
    /// The second position channel's reading at the tick (converter counts), where fitted.
    pub abs_count: Option<u16>,
}

/// A recorded excitation of one joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// The control period, s.
    pub period_s: f64,
    /// The bridge supply, V (duty 1 applies it).
    pub supply_v: f64,
    /// Encoder counts per joint unit (counts/m, counts/rad).
    pub counts_per_unit: f64,
    /// The second channel's counts per joint unit, where fitted.
    pub abs_counts_per_unit: Option<f64>,
    /// The samples, one per tick; the last closes the last period.
    pub samples: Vec<Sample>,
}

impl Recording {
    /// The encoder position of sample `k` relative to the first, joint units.
    pub fn position(&self, k: usize) -> f64 {
        match (self.samples.get(k), self.samples.first()) {
            (Some(s), Some(s0)) => (s.count - s0.count) as f64 / self.counts_per_unit,
            _ => f64::NAN,
        }
    }
}
