//! The tree written as URDF (XML): links with visual primitives and colours, joints with
//! their origin (xyz, and rpy: R = Rz(yaw) Ry(pitch) Rx(roll), URDF's fixed axes), axis and
//! limits. Numbers are written with Rust's shortest round-trip form, so a reader gets the
//! very f64 values of the model.

use crate::model::{JointType, Shape, Tree, MATERIALS};
use nalgebra::Isometry3;
use std::fmt::Write;

/// XML escaping for names and attribute values.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A number: exact zero as `0`, otherwise the shortest form that reads back to the same f64.
fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x:?}")
    }
}

fn origin(o: &Isometry3<f64>) -> String {
    let t = o.translation.vector;
    let (r, p, y) = o.rotation.euler_angles();
    format!(
        r#"<origin xyz="{} {} {}" rpy="{} {} {}"/>"#,
        num(t.x),
        num(t.y),
        num(t.z),
        num(r),
        num(p),
        num(y)
    )
}

/// The URDF text of a tree. `comment` goes into an XML comment at the top (where the
/// geometry came from).
pub fn to_urdf(tree: &Tree, comment: &str) -> String {
    let mut s = String::new();
    // Writing to a String cannot fail.
    let _ = writeln!(s, r#"<?xml version="1.0"?>"#);
    let _ = writeln!(s, "<!-- {} -->", comment.replace("--", "- -"));
    let _ = writeln!(s, r#"<robot name="{}">"#, esc(&tree.name));
    for (name, [r, g, b, a]) in MATERIALS {
        let _ = writeln!(
            s,
            r#"  <material name="{name}"><color rgba="{} {} {} {}"/></material>"#,
            num(r),
            num(g),
            num(b),
            num(a)
        );
    }
    for link in &tree.links {
        if link.visuals.is_empty() {
            let _ = writeln!(s, r#"  <link name="{}"/>"#, esc(&link.name));
            continue;
        }
        let _ = writeln!(s, r#"  <link name="{}">"#, esc(&link.name));
        for v in &link.visuals {
            let geometry = match v.shape {
                Shape::Cylinder { radius, length } => format!(
                    r#"<cylinder radius="{}" length="{}"/>"#,
                    num(radius),
                    num(length)
                ),
                Shape::Box { size: [x, y, z] } => {
                    format!(r#"<box size="{} {} {}"/>"#, num(x), num(y), num(z))
                }
                Shape::Sphere { radius } => format!(r#"<sphere radius="{}"/>"#, num(radius)),
            };
            let _ = writeln!(
                s,
                r#"    <visual>{}<geometry>{geometry}</geometry><material name="{}"/></visual>"#,
                origin(&v.origin),
                v.material
            );
        }
        let _ = writeln!(s, "  </link>");
    }
    for j in &tree.joints {
        let _ = writeln!(
            s,
            r#"  <joint name="{}" type="{}">"#,
            esc(&j.name),
            j.kind.urdf_name()
        );
        let _ = writeln!(s, r#"    <parent link="{}"/>"#, esc(&j.parent));
        let _ = writeln!(s, r#"    <child link="{}"/>"#, esc(&j.child));
        let _ = writeln!(s, "    {}", origin(&j.origin));
        if j.kind != JointType::Fixed {
            let _ = writeln!(
                s,
                r#"    <axis xyz="{} {} {}"/>"#,
                num(j.axis.x),
                num(j.axis.y),
                num(j.axis.z)
            );
        }
        match j.kind {
            JointType::Revolute {
                lower,
                upper,
                effort,
                velocity,
            }
            | JointType::Prismatic {
                lower,
                upper,
                effort,
                velocity,
            } => {
                let _ = writeln!(
                    s,
                    r#"    <limit lower="{}" upper="{}" effort="{}" velocity="{}"/>"#,
                    num(lower),
                    num(upper),
                    num(effort),
                    num(velocity)
                );
            }
            JointType::Continuous | JointType::Fixed => {}
        }
        let _ = writeln!(s, "  </joint>");
    }
    let _ = writeln!(s, "</robot>");
    s
}
