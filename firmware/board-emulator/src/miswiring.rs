//! The miswirings a robot just built may have, injected into the emulated board's
//! mechanics (`board_on_plant::Wiring`, [`crate::mechanics::MechanicsConfig::wiring`]) from
//! text: `serve --miswire KIND=JOINTS`, one option per miswiring, for the commissioning a
//! lab runs on a board on a desk (`host-sim commission --connect`).
//!
//! | text | the miswiring |
//! | --- | --- |
//! | `motor-reversed=l1` | the motor's leads reversed: a positive duty drives the joint to -q |
//! | `encoder-reversed=theta1` | the encoder's A and B swapped: it counts down towards +q |
//! | `encoders-swapped=l2,theta2` | two encoders' cables swapped: each counter reads the other's |
//! | `gear-scale=l3:1.1` | the counts per joint unit 1.1 times the drawing's (a gear ratio 10 % off) |
//! | `switch-normally-open=l1` | a normally open home switch where a normally closed one is expected |
//! | `brake-inverted=theta3` | the brake holds when the board releases it, and the reverse |
//!
//! A joint is named `l1`, `l2`, `l3`, `theta1`, `theta2`, `theta3` or by its index 0..5.

use board_on_plant::Wiring;
use plant::NUM_JOINTS;

/// The joints' names, joint order.
pub const JOINT_NAMES: [&str; NUM_JOINTS] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// A gear scale beyond this factor either way is not a gear ratio off but a wrong number
/// (the encoder's counts per unit would be off by more than a factor of 10).
pub const GEAR_SCALE_MAX: f64 = 10.0;

/// Why a miswiring's text was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MiswiringError {
    /// Not `KIND=VALUE`.
    #[error("miswiring `{0}`: expected KIND=JOINT (e.g. motor-reversed=l1, encoders-swapped=l2,theta2, gear-scale=l3:1.1)")]
    Form(String),
    /// An unknown kind.
    #[error("miswiring `{0}`: unknown kind (motor-reversed, encoder-reversed, encoders-swapped, gear-scale, switch-normally-open, brake-inverted)")]
    Kind(String),
    /// An unknown joint.
    #[error(
        "miswiring `{text}`: `{joint}` is not a joint (l1, l2, l3, theta1, theta2, theta3 or 0..5)"
    )]
    Joint {
        /// The whole text.
        text: String,
        /// The joint as written.
        joint: String,
    },
    /// `encoders-swapped` needs two different joints.
    #[error("miswiring `{0}`: encoders-swapped needs two different joints (e.g. l2,theta2)")]
    Pair(String),
    /// Only one pair of encoders can be swapped.
    #[error("miswiring `{0}`: a pair of encoders is swapped already (one pair at most)")]
    SecondPair(String),
    /// A gear scale that is not a positive number within [`GEAR_SCALE_MAX`] either way.
    #[error("miswiring `{0}`: the gear scale must be a number between 0.1 and 10 (e.g. gear-scale=l3:1.1)")]
    Scale(String),
}

/// Joint `name` (a name of [`JOINT_NAMES`] or its index).
fn joint(text: &str, name: &str) -> Result<usize, MiswiringError> {
    let name = name.trim();
    JOINT_NAMES
        .iter()
        .position(|n| n.eq_ignore_ascii_case(name))
        .or_else(|| name.parse::<usize>().ok().filter(|j| *j < NUM_JOINTS))
        .ok_or_else(|| MiswiringError::Joint {
            text: text.into(),
            joint: name.into(),
        })
}

/// Adds the miswiring `text` (see the module documentation) to `wiring`.
pub fn add(wiring: &mut Wiring, text: &str) -> Result<(), MiswiringError> {
    let (kind, value) = text
        .split_once('=')
        .ok_or_else(|| MiswiringError::Form(text.into()))?;
    match kind.trim() {
        "motor-reversed" => wiring.motor_reversed[joint(text, value)?] = true,
        "encoder-reversed" => wiring.encoder_reversed[joint(text, value)?] = true,
        "switch-normally-open" => wiring.switch_normally_open[joint(text, value)?] = true,
        "brake-inverted" => wiring.brake_inverted[joint(text, value)?] = true,
        "encoders-swapped" => {
            let (a, b) = value
                .split_once(',')
                .ok_or_else(|| MiswiringError::Pair(text.into()))?;
            let (a, b) = (joint(text, a)?, joint(text, b)?);
            if a == b {
                return Err(MiswiringError::Pair(text.into()));
            }
            if wiring.encoders_swapped.is_some() {
                return Err(MiswiringError::SecondPair(text.into()));
            }
            wiring.encoders_swapped = Some((a, b));
        }
        "gear-scale" => {
            let (j, scale) = value
                .split_once(':')
                .ok_or_else(|| MiswiringError::Scale(text.into()))?;
            let j = joint(text, j)?;
            let scale: f64 = scale
                .trim()
                .parse()
                .map_err(|_| MiswiringError::Scale(text.into()))?;
            if !(1.0 / GEAR_SCALE_MAX..=GEAR_SCALE_MAX).contains(&scale) {
                return Err(MiswiringError::Scale(text.into()));
            }
            wiring.count_scale[j] = scale;
        }
        _ => return Err(MiswiringError::Kind(text.into())),
    }
    Ok(())
}

/// The wiring with every miswiring of `texts` (straight without any).
pub fn parse<S: AsRef<str>>(texts: &[S]) -> Result<Wiring, MiswiringError> {
    let mut w = Wiring::straight();
    for t in texts {
        add(&mut w, t.as_ref())?;
    }
    Ok(w)
}

/// The miswirings of `wiring` in the text [`add`] reads, one per miswiring (none: straight).
pub fn describe(wiring: &Wiring) -> Vec<String> {
    let mut out = Vec::new();
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        if wiring.motor_reversed[j] {
            out.push(format!("motor-reversed={name}"));
        }
        if wiring.encoder_reversed[j] {
            out.push(format!("encoder-reversed={name}"));
        }
        if wiring.count_scale[j] != 1.0 {
            out.push(format!("gear-scale={name}:{}", wiring.count_scale[j]));
        }
        if wiring.switch_normally_open[j] {
            out.push(format!("switch-normally-open={name}"));
        }
        if wiring.brake_inverted[j] {
            out.push(format!("brake-inverted={name}"));
        }
    }
    if let Some((a, b)) = wiring.encoders_swapped {
        let name = |j: usize| JOINT_NAMES.get(j).copied().unwrap_or("?");
        out.push(format!("encoders-swapped={},{}", name(a), name(b)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind reads into its field of the wiring, and `describe` writes it back.
    #[test]
    fn every_kind_reads_and_writes_back() -> Result<(), MiswiringError> {
        let texts = [
            "motor-reversed=l1",
            "encoder-reversed=theta1",
            "gear-scale=l3:1.1",
            "switch-normally-open=2",
            "brake-inverted=theta3",
            "encoders-swapped=l2,theta2",
        ];
        let w = parse(&texts)?;
        assert!(w.motor_reversed[0] && w.encoder_reversed[3] && w.brake_inverted[5]);
        assert!(w.switch_normally_open[2]);
        assert_eq!(w.count_scale[2], 1.1);
        assert_eq!(w.encoders_swapped, Some((1, 4)));
        assert_eq!(parse(&describe(&w))?, w);
        assert!(parse::<&str>(&[])?.is_straight());
        Ok(())
    }

    /// Bad text is refused with what was wrong.
    #[test]
    fn bad_text_is_refused() {
        let bad = |t: &str| parse(&[t]).err();
        assert!(matches!(
            bad("motor-reversed"),
            Some(MiswiringError::Form(_))
        ));
        assert!(matches!(
            bad("motor-swapped=l1"),
            Some(MiswiringError::Kind(_))
        ));
        assert!(matches!(
            bad("motor-reversed=l4"),
            Some(MiswiringError::Joint { .. })
        ));
        assert!(matches!(
            bad("motor-reversed=6"),
            Some(MiswiringError::Joint { .. })
        ));
        assert!(matches!(
            bad("encoders-swapped=l1,l1"),
            Some(MiswiringError::Pair(_))
        ));
        assert!(matches!(
            bad("encoders-swapped=l1"),
            Some(MiswiringError::Pair(_))
        ));
        assert!(matches!(
            bad("gear-scale=l1:-1"),
            Some(MiswiringError::Scale(_))
        ));
        assert!(matches!(
            bad("gear-scale=l1:NaN"),
            Some(MiswiringError::Scale(_))
        ));
        assert!(matches!(
            bad("gear-scale=l1"),
            Some(MiswiringError::Scale(_))
        ));
        assert!(matches!(
            parse(&["encoders-swapped=l1,l2", "encoders-swapped=l3,theta1"]),
            Err(MiswiringError::SecondPair(_))
        ));
    }
}
