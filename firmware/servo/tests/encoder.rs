#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Encoder extension, joint units and homing.
use board_profile::BoardProfile;
use hal::QuadratureCounter;
use proptest::prelude::*;

/// The reference board's leg encoder, counts per metre.
fn leg_counts_per_m() -> f64 {
    BoardProfile::REFERENCE.joints[0].counts_per_unit()
}

/// The reference board's link encoder, counts per radian.
fn link_counts_per_rad() -> f64 {
    BoardProfile::REFERENCE.joints[3].counts_per_unit()
}
use servo::{CountExtender, EncoderConfig, Encoders, JointEncoder};

/// The hardware counter for a true (unbounded) count: the low 16 bits.
fn raw(true_count: i64) -> u16 {
    true_count.rem_euclid(1 << 16) as u16
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property: any sequence of increments with |delta| < 32768 per read, starting
    /// anywhere, reproduces the true count exactly after every read.
    #[test]
    fn extension_reproduces_the_true_count_for_any_increments(
        start in any::<i32>(),
        deltas in prop::collection::vec(-32767i64..=32767, 1..2000),
    ) {
        let mut truth = i64::from(start);
        let mut ext = CountExtender::starting_at(raw(truth), truth);
        for d in deltas {
            truth += d;
            prop_assert_eq!(ext.update(raw(truth)), truth);
        }
    }

    /// Property: long one-directional runs (many wraps) in both directions keep every
    /// count: large same-signed increments wrap the 16-bit counter every 2..3 reads.
    #[test]
    fn extension_survives_many_wraps_in_both_directions(
        runs in prop::collection::vec((any::<bool>(), prop::collection::vec(20_000i64..=32_767, 10..200)), 1..10),
    ) {
        let mut truth = 0i64;
        let mut ext = CountExtender::new();
        let mut wraps = 0u32;
        for (up, deltas) in runs {
            for d in deltas {
                let before = raw(truth);
                truth += if up { d } else { -d };
                let after = raw(truth);
                if (up && after < before) || (!up && after > before) {
                    wraps += 1;
                }
                prop_assert_eq!(ext.update(after), truth);
            }
        }
        prop_assert!(wraps >= 3);
    }

    /// Property: the board's two counter widths. Four encoders are on 16-bit timers (TIM1,
    /// TIM3, TIM4, TIM8: the counter wraps at ARR = 0xFFFF), two on 32-bit timers (TIM2,
    /// TIM5: ARR stays at its reset value 0xFFFF_FFFF, the counter wraps at 2^32), and
    /// the firmware reads the low 16 bits of both. For any 32-bit hardware counter (start
    /// anywhere, wrapping through 2^32 included) and any increments below 2^15 per read,
    /// the extension of the low 16 bits reproduces the true count: 2^16 divides 2^32, so
    /// the low 16 bits of a 32-bit wrap are a 16-bit wrap.
    #[test]
    fn extension_is_exact_for_16_and_32_bit_counters(
        start in any::<u32>(),
        wide in any::<bool>(),
        deltas in prop::collection::vec(-32767i64..=32767, 1..2000),
    ) {
        let width: u32 = if wide { 32 } else { 16 };
        let modulus = 1i128 << width;
        let hw = |truth: i64| -> u16 {
            // The hardware counter of this width, then the 16 bits the firmware reads.
            let c = (i128::from(truth)).rem_euclid(modulus);
            (c & 0xFFFF) as u16
        };
        let mut truth = if wide { i64::from(start) } else { i64::from(start & 0xFFFF) };
        let mut ext = CountExtender::starting_at(hw(truth), truth);
        for d in deltas {
            truth += d;
            prop_assert_eq!(ext.update(hw(truth)), truth);
        }
    }
}

/// The fastest joint moves far fewer counts per control period than the extension's
/// limit (2^15 per read): the legs' no-load speed, 378 mm/s, is 252 counts per ms at
/// 0.0015 mm/count; the links' 28 rad/s, 1 605 counts per ms at 0.005 deg/count.
#[test]
fn the_top_speeds_stay_far_below_the_extension_limit() {
    let per_ms = |speed: f64, counts_per_unit: f64| speed * counts_per_unit * 1e-3;
    let leg = per_ms(0.378, leg_counts_per_m());
    let link = per_ms(28.0, link_counts_per_rad());
    assert!(leg < 300.0 && link < 1700.0, "{leg} {link}");
    assert!(
        leg.max(link) * 10.0 < 32_768.0,
        "ten missed ticks still extend exactly"
    );
}

#[test]
fn the_first_read_from_a_reset_counter_is_signed() {
    // Counter at raw 0 after reset; a small negative motion reads as -5, not 65531.
    let mut ext = CountExtender::new();
    assert_eq!(ext.update(65531), -5);
    assert_eq!(ext.update(3), 3);
}

#[test]
fn a_step_of_32768_counts_is_the_documented_limit() {
    // Exactly half a counter range is ambiguous and reads as -32768: the documented
    // maximum speed is fewer than 32768 counts between reads.
    let mut ext = CountExtender::new();
    assert_eq!(ext.update(32767), 32767);
    let mut ext = CountExtender::new();
    assert_eq!(ext.update(32768), -32768);
}

#[test]
fn leg_conversion_is_2000_counts_per_3_mm() {
    let mut e = JointEncoder::<f64>::new(leg_counts_per_m());
    assert!((e.update(2000) - 0.003).abs() < 1e-12);
    assert!((e.resolution() - 1.5e-6).abs() < 1e-15);
    // Max speed at a 1 kHz read rate: 32767 counts/ms = 49.15 m/s.
    assert!((e.max_speed(1e-3) - 49.15).abs() < 0.01);
}

#[test]
fn link_conversion_is_2000_counts_per_10_degrees() {
    let mut e = JointEncoder::<f64>::new(link_counts_per_rad());
    assert!((link_counts_per_rad() - 11_459.156).abs() < 1e-3);
    let q = e.update(2000);
    assert!((q.to_degrees() - 10.0).abs() < 1e-9);
    // -1 count = -0.005 deg.
    let mut e = JointEncoder::<f64>::new(link_counts_per_rad());
    assert!((e.update(u16::MAX).to_degrees() + 0.005).abs() < 1e-12);
}

#[test]
fn homing_makes_the_current_count_read_the_given_position_and_keeps_the_scale() {
    let mut e = JointEncoder::<f64>::new(leg_counts_per_m());
    e.update(12_345);
    e.set_position(0.050); // homed at 50 mm
    assert!((e.position() - 0.050).abs() < 1e-12);
    // 2000 counts further (with a wrap on the way) = 3 mm further.
    e.update(12_345u16.wrapping_add(30_000));
    e.update(12_345u16.wrapping_add(60_000));
    e.update(12_345u16.wrapping_add(62_000));
    assert!((e.position() - (0.050 + 62_000.0 * 1.5e-6)).abs() < 1e-12);
    // Non-finite homing values are ignored.
    let before = e.position();
    e.set_position(f64::NAN);
    assert_eq!(e.position(), before);
}

#[test]
fn f32_keeps_one_count_resolution_near_the_homing_point_far_from_count_zero() {
    // 100 000 000 counts from power-up, homed there: f32 still resolves one count.
    let mut e = JointEncoder::<f32>::new(leg_counts_per_m() as f32);
    let mut truth = 0i64;
    for _ in 0..4000 {
        truth += 25_000;
        e.update(raw(truth));
    }
    assert_eq!(e.count(), 100_000_000);
    e.set_position(0.1);
    e.update(raw(truth + 1));
    assert!((e.position() - (0.1 + 1.5e-6)).abs() < 1e-8);
}

struct FakeCounters([u16; 6]);

impl QuadratureCounter for FakeCounters {
    fn counts(&mut self) -> [u16; 6] {
        self.0
    }
}

#[test]
fn six_encoders_read_through_the_hal_trait_in_joint_units() {
    let config = EncoderConfig::<f64>::default();
    let mut enc = Encoders::new(&config).unwrap();
    let mut hw = FakeCounters([2000, 63536, 0, 2000, 0, 65535]);
    assert_eq!(hw.count(1), Some(63536));
    assert_eq!(hw.count(6), None);
    let q = enc.read(&mut hw);
    assert!((q[0] - 0.003).abs() < 1e-12);
    assert!((q[1] + 0.003).abs() < 1e-12);
    assert!((q[3].to_degrees() - 10.0).abs() < 1e-9);
    assert!((q[5].to_degrees() + 0.005).abs() < 1e-12);
    enc.set_positions(&[0.1, 0.2, 0.3, 1.0, 2.0, 3.0]);
    assert_eq!(enc.positions(), [0.1, 0.2, 0.3, 1.0, 2.0, 3.0]);
    assert!(enc.set_position(2, 0.0));
    assert!(!enc.set_position(6, 0.0));
    // Starting at arbitrary raw values reads 0 there.
    let enc = Encoders::starting_at(&config, &[100, 200, 300, 400, 500, 600]).unwrap();
    assert_eq!(enc.positions(), [0.0; 6]);
}

#[test]
fn encoder_config_rejects_a_non_positive_resolution_naming_field_and_joint() {
    let mut config = EncoderConfig::<f64>::default();
    config.counts_per_unit[4] = 0.0;
    let err = config.validate().unwrap_err();
    assert_eq!(err.field, "counts_per_unit");
    assert_eq!(err.joint, 4);
    assert_eq!(
        err.to_string(),
        "encoder.counts_per_unit of joint 4 (theta2) must be finite and > 0"
    );
}
