//! The second position channel's converter, chosen by the numbers: the channel's
//! cross-check (`control::absolute::ChannelConfig::reference`) trips when the two channels
//! disagree by more than `agree` (five filtered deviations of the reading, the converter's
//! quantisation `step^2 / 12` among them), so the motion a failed encoder hides before it is
//! caught is `agree` per joint. Mapped to the platform through the Jacobian (the largest over
//! the task box, `safety::standstill_platform`), it must stay within the 0.1 mm the
//! held-stop requirement allows an encoder fault (detected within 0.1 mm of motion).

use board_profile::position_channel::PositionChannel;
use control::absolute::{ChannelCalibration, ChannelConfig};
use control::runtime::reference_config_for;
use control::safety::standstill_platform;
use kinematics_core::{Branch, RsprGeometry};

/// The motion an encoder fault may hide before the cross-check trips, per joint and at the
/// platform, for the channel `channel`.
fn hidden(channel: &PositionChannel) -> ([f64; 6], f64) {
    let robot = RsprGeometry::<f64>::reference();
    let cfg = reference_config_for(&robot, Branch::OUTER, None, None).unwrap();
    let cal = ChannelCalibration::of(channel, &cfg.mechanics.range);
    let widths = cfg.controller.servo.backlash.joints.map(|b| b.width);
    let continuous = cfg.current.motors.map(|m| m.continuous_a);
    let check = ChannelConfig::reference(
        &cal,
        &cfg.controller.encoders.counts_per_unit,
        &widths,
        &cfg.encoder_check.top_speed,
        &continuous,
        1.0 / cfg.controller.rate_hz,
    );
    (check.agree, standstill_platform(&cfg, &robot, &check.agree))
}

/// Property: the AD7689's 16 bits hide at most 0.1 mm of platform motion behind a failed
/// encoder, and the STM32F405's own 12-bit ADC over the same potentiometers does not meet
/// the bound on the links (its step, 0.083 deg, is three times the 16-bit channel's whole
/// `agree`); the reference board's channel (the one the firmware builds) is the 16-bit one.
#[test]
fn sixteen_bits_meet_the_bound_and_twelve_do_not() {
    const BOUND_M: f64 = 0.1e-3;
    let (agree16, platform16) = hidden(&PositionChannel::REFERENCE);
    let (agree12, platform12) = hidden(&PositionChannel::ON_CHIP_12_BIT);
    println!(
        "16 bits: agree {:.1} um (leg), {:.4} deg (link), {:.1} um at the platform; \
         12 bits: {:.1} um, {:.4} deg, {:.1} um",
        agree16[0] * 1e6,
        agree16[3].to_degrees(),
        platform16 * 1e6,
        agree12[0] * 1e6,
        agree12[3].to_degrees(),
        platform12 * 1e6
    );
    assert!(platform16 <= BOUND_M, "16 bits: {platform16} m");
    assert!(platform12 > BOUND_M, "12 bits: {platform12} m");
    assert!(PositionChannel::ON_CHIP_12_BIT.step_unit(3) > 3.0 * agree16[3]);
    assert_eq!(PositionChannel::REFERENCE.bits, 16);
    let robot = RsprGeometry::<f64>::reference();
    let cfg = reference_config_for(&robot, Branch::OUTER, None, None).unwrap();
    assert_eq!(
        cfg.channel.agree, agree16,
        "the firmware's channel is the 16-bit one"
    );
}
