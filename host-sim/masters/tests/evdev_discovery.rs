#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Finding the SpaceMouse among the input devices through a sysfs tree (a fake one in a
//! temporary directory, laid out as `/sys/class/input`): by 3Dconnexion vendor id, by
//! name, by USB id; other nodes and incomplete entries are skipped; nothing matching is
//! a `NotFound` error naming what was wanted.

use masters::evdev::{find_device, list_devices, DeviceMatch};
use masters::DeviceError;
use std::fs;
use std::path::Path;

fn device(root: &Path, node: &str, name: &str, vendor: &str, product: &str) {
    let d = root.join(node).join("device");
    fs::create_dir_all(d.join("id")).unwrap();
    fs::write(d.join("name"), format!("{name}\n")).unwrap();
    fs::write(d.join("id/vendor"), format!("{vendor}\n")).unwrap();
    fs::write(d.join("id/product"), format!("{product}\n")).unwrap();
}

#[test]
fn finds_the_spacemouse() {
    let dir = tempfile::tempdir().unwrap();
    let sys = dir.path().join("class/input");
    device(
        &sys,
        "event2",
        "AT Translated Set 2 keyboard",
        "0001",
        "0001",
    );
    device(&sys, "event5", "3Dconnexion SpaceNavigator", "046d", "c626");
    device(
        &sys,
        "event9",
        "3Dconnexion SpaceMouse Compact",
        "256f",
        "c635",
    );
    device(&sys, "mouse0", "3Dconnexion SpaceNavigator", "046d", "c626");
    fs::create_dir_all(sys.join("event11/device")).unwrap(); // no name: skipped
    let dev = Path::new("/dev/input");
    let all = list_devices(&sys, dev);
    assert_eq!(
        all.iter()
            .map(|d| d.path.display().to_string())
            .collect::<Vec<_>>(),
        [
            "/dev/input/event2",
            "/dev/input/event5",
            "/dev/input/event9"
        ]
    );
    let d = find_device(&DeviceMatch::Any3Dconnexion, &sys, dev).unwrap();
    assert_eq!(
        (d.path.as_path(), d.vendor, d.product),
        (Path::new("/dev/input/event5"), 0x046d, 0xc626)
    );
    let d = find_device(
        &DeviceMatch::NameContains("spacemouse compact".into()),
        &sys,
        dev,
    )
    .unwrap();
    assert_eq!(d.path, Path::new("/dev/input/event9"));
    let d = find_device(&DeviceMatch::UsbId(0x256f, 0xc635), &sys, dev).unwrap();
    assert_eq!(d.name, "3Dconnexion SpaceMouse Compact");
    let e = find_device(&DeviceMatch::UsbId(0x1234, 0x5678), &sys, dev).unwrap_err();
    assert!(matches!(e, DeviceError::NotFound { .. }), "{e}");
    assert!(e.to_string().contains("UsbId(4660, 22136)"), "{e}");
}
