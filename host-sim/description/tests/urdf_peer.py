"""The robot description against a URDF reader the project did not write (yourdfpy).

    python3 urdf_peer.py ROBOT.urdf STATES.csv [--symmetric]

STATES.csv is `host-sim describe --joint-states` output joined with the controller's
forward kinematics (`host-sim fk`) by row: the columns fk_x_mm..fk_rz_deg (the controller's
pose), then every moving joint of the description (<joint>_mm or <joint>_deg). For every
row, yourdfpy poses the description with the joint values and
- the platform frame must equal the controller's pose: position within 1e-6 m, rotation
  within 1e-6 (Frobenius norm of the difference of the rotation matrices, about the angle
  in rad);
- chains 2 and 3, which the tree leaves open, must close: every pin's frame, seen from the
  platform frame, must stay as it is at the first pose (centre within 1e-6 m, orientation
  within 1e-6): a pin is the platform's joint, turning with it, whatever the pose; and on
  a symmetric robot (--symmetric: the reference RSPR and USR) pins 2 and 3 are pin 1
  turned by 120 and 240 deg about the platform's z axis (CONVENTIONS.md, Eq. 6.3-6.4).
Exits non-zero with the first failure.
"""

import csv
import math
import sys

import numpy as np
import yourdfpy

TOL_M = 1e-6
TOL_R = 1e-6


def rotvec_matrix(r):
    """R = exp([r]x) (Rodrigues), r in rad."""
    angle = math.sqrt(sum(x * x for x in r))
    if angle < 1e-300:
        return np.eye(3)
    k = np.array(r) / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def main():
    urdf_path, states_path = sys.argv[1], sys.argv[2]
    symmetric = "--symmetric" in sys.argv[3:]
    robot = yourdfpy.URDF.load(urdf_path, load_meshes=False, build_scene_graph=True)
    moving = robot.actuated_joint_names
    rows = list(csv.DictReader(open(states_path)))
    if len(rows) < 50:
        sys.exit(f"FAIL: {len(rows)} rows, the test wants at least 50 poses")
    worst_t = worst_r = worst_pin = 0.0
    pin_ref = None
    for k, row in enumerate(rows):
        if row.get("error"):
            sys.exit(f"FAIL: row {k + 2}: {row['error']}")
        cfg = {}
        for name in moving:
            if f"{name}_mm" in row:
                cfg[name] = float(row[f"{name}_mm"]) / 1000.0
            elif f"{name}_deg" in row:
                cfg[name] = math.radians(float(row[f"{name}_deg"]))
            else:
                sys.exit(f"FAIL: joint {name} of the URDF has no column in {states_path}")
        robot.update_cfg(cfg)
        T = robot.get_transform(frame_to="platform", frame_from="base")
        t = np.array([float(row[f"fk_{c}_mm"]) for c in "xyz"]) / 1000.0
        R = rotvec_matrix([math.radians(float(row[f"fk_r{c}_deg"])) for c in "xyz"])
        dt = float(np.linalg.norm(T[:3, 3] - t))
        dr = float(np.linalg.norm(T[:3, :3] - R))
        worst_t, worst_r = max(worst_t, dt), max(worst_r, dr)
        if dt > TOL_M or dr > TOL_R:
            sys.exit(f"FAIL: row {k + 2}: the URDF's platform is {dt:.3e} m, {dr:.3e} rad "
                     f"from the controller's forward kinematics")
        # Each pin frame in the platform frame: T^-1 P.
        pins = [np.linalg.inv(T) @ robot.get_transform(frame_to=f"pin{i}_link", frame_from="base")
                for i in (1, 2, 3)]
        if pin_ref is None:
            pin_ref = pins
        d = max(max(float(np.linalg.norm(a[:3, 3] - b[:3, 3])),
                    float(np.linalg.norm(a[:3, :3] - b[:3, :3])))
                for a, b in zip(pins, pin_ref))
        if symmetric:
            for i, p in ((1, pins[1]), (2, pins[2])):
                a = 2 * math.pi * i / 3
                rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
                d = max(d, float(np.linalg.norm(rz @ pins[0][:3, 3] - p[:3, 3])),
                        float(np.linalg.norm(rz @ pins[0][:3, :3] - p[:3, :3])))
        worst_pin = max(worst_pin, d)
        if d > TOL_M:
            sys.exit(f"FAIL: row {k + 2}: a pin frame is off by {d:.3e} (m, or rad) on the platform: "
                     f"chains 2 and 3 do not close on the platform")
    print(f"URDF with yourdfpy {yourdfpy.__version__ if hasattr(yourdfpy, '__version__') else ''}: "
          f"{len(rows)} poses; worst platform error {worst_t:.2e} m, {worst_r:.2e} rad; "
          f"worst pin frame error on the platform {worst_pin:.2e} m (bounds {TOL_M} m, {TOL_R} rad): OK")


if __name__ == "__main__":
    main()
