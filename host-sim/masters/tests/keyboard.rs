#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The keyboard mapping, without a terminal: key events in, twist and buttons out.

use masters::keyboard::{
    Key, KeyAction, KeyEvent, KeyOutcome, KeyboardConfig, KeyboardConfigError, KeyboardMaster,
    ReleaseMode,
};
use masters::{Master, MasterInput};
use nalgebra::Vector3;

fn ev(key: Key, action: KeyAction, t_s: f64) -> KeyEvent {
    KeyEvent { key, action, t_s }
}

/// With releases reported: a held key moves at the step's speed until released; opposite
/// keys cancel; rotation keys give angular velocity; speed steps clamp at the ends of the
/// list (and say so).
#[test]
fn held_keys_with_releases() {
    let mut k = KeyboardMaster::new(KeyboardConfig {
        release: ReleaseMode::Reported,
        ..KeyboardConfig::default()
    })
    .unwrap();
    let (v, w) = k.speed();
    assert_eq!((v, w), (0.002, 5f64.to_radians()));
    assert_eq!(
        k.handle(&ev(Key::Char('d'), KeyAction::Press, 0.0)),
        KeyOutcome::Motion
    );
    k.handle(&ev(Key::Up, KeyAction::Press, 0.0));
    k.handle(&ev(Key::Char('U'), KeyAction::Press, 0.0));
    let t = k.twist(10.0);
    assert_eq!(t.linear_m_s, Vector3::new(v, v, 0.0));
    assert_eq!(t.angular_rad_s, Vector3::new(0.0, 0.0, w));
    k.handle(&ev(Key::Char('a'), KeyAction::Press, 0.0));
    assert_eq!(k.twist(10.0).linear_m_s.x, 0.0, "opposite keys cancel");
    k.handle(&ev(Key::Char('a'), KeyAction::Release, 0.1));
    k.handle(&ev(Key::Char('d'), KeyAction::Release, 0.1));
    k.handle(&ev(Key::Up, KeyAction::Release, 0.1));
    k.handle(&ev(Key::Char('u'), KeyAction::Release, 0.1));
    assert_eq!(k.twist(10.0).to_array(), [0.0; 6]);
    for _ in 0..10 {
        k.handle(&ev(Key::Char('+'), KeyAction::Press, 0.2));
    }
    assert_eq!(
        k.handle(&ev(Key::Char('='), KeyAction::Press, 0.2)),
        KeyOutcome::Speed(4, 0.010, 20f64.to_radians())
    );
    for _ in 0..10 {
        k.handle(&ev(Key::Char('-'), KeyAction::Press, 0.2));
    }
    assert_eq!(k.speed().0, 0.0005);
}

/// Without releases: a key acts until hold_s after its last press or repeat.
#[test]
fn timeout_mode() {
    let mut k = KeyboardMaster::new(KeyboardConfig::default()).unwrap();
    k.handle(&ev(Key::PageUp, KeyAction::Press, 1.0));
    assert!(k.twist(1.5).linear_m_s.z > 0.0);
    assert_eq!(k.twist(1.61).linear_m_s.z, 0.0, "0.6 s after the press");
    k.handle(&ev(Key::PageUp, KeyAction::Repeat, 1.6));
    assert!(k.twist(2.1).linear_m_s.z > 0.0, "a repeat extends it");
}

/// Clutch and presence toggles, Esc stops everything; the master trait reports them.
#[test]
fn toggles_and_stop() {
    let mut k = KeyboardMaster::new(KeyboardConfig::default()).unwrap();
    assert_eq!(
        k.handle(&ev(Key::Char(' '), KeyAction::Press, 0.0)),
        KeyOutcome::OperatorPresent(true)
    );
    assert_eq!(
        k.handle(&ev(Key::Char('c'), KeyAction::Press, 0.0)),
        KeyOutcome::Clutch(true)
    );
    assert_eq!(
        k.handle(&ev(Key::Char('c'), KeyAction::Repeat, 0.05)),
        KeyOutcome::Ignored,
        "repeats do not toggle"
    );
    k.handle(&ev(Key::Char('w'), KeyAction::Press, 0.1));
    let s = k.poll(0.2).unwrap().unwrap();
    assert!(s.buttons.clutch && s.buttons.operator_present);
    let MasterInput::Twist(t) = s.input else {
        panic!("rate")
    };
    assert!(t.linear_m_s.y > 0.0);
    assert_eq!(
        k.handle(&ev(Key::Esc, KeyAction::Press, 0.3)),
        KeyOutcome::Stopped
    );
    let s = k.poll(0.31).unwrap().unwrap();
    assert!(!s.buttons.clutch && !s.buttons.operator_present);
    let MasterInput::Twist(t) = s.input else {
        panic!("rate")
    };
    assert_eq!(t.to_array(), [0.0; 6]);
    assert_eq!(
        k.handle(&ev(Key::Char('x'), KeyAction::Press, 0.4)),
        KeyOutcome::Ignored
    );
}

#[test]
fn bad_settings_are_refused() {
    let c = KeyboardConfig {
        speeds: vec![],
        ..KeyboardConfig::default()
    };
    assert_eq!(
        KeyboardMaster::new(c).err(),
        Some(KeyboardConfigError::NoSpeeds)
    );
    let c = KeyboardConfig {
        speeds: vec![(0.001, -1.0)],
        initial_step: 0,
        ..KeyboardConfig::default()
    };
    assert!(matches!(
        KeyboardMaster::new(c),
        Err(KeyboardConfigError::BadSpeed { step: 0, .. })
    ));
    let c = KeyboardConfig {
        initial_step: 9,
        ..KeyboardConfig::default()
    };
    assert!(matches!(
        KeyboardMaster::new(c),
        Err(KeyboardConfigError::InitialStep { .. })
    ));
}
