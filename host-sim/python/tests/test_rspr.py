"""The Python module `rspr` against the command line and the kinematics' own properties.

The CLI comparisons run `host-sim` (the binary named by RSPR_HOST_SIM, else
target/debug/host-sim of this repository) in its batch form on the same poses and require
every number the CLI prints to be *the same text* as the module's float formatted the way
the CLI formats it (`robot_config::units::fixed9` / `significant`, mirrored below): the
module and the CLI run the same Rust code, so they must agree to the last printed digit
(1e-9 mm and deg for joints and poses, ten significant digits for SI values), not merely
to a tolerance.
"""

import csv
import io
import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

import rspr

ROOT = pathlib.Path(__file__).resolve().parents[3]
HOST_SIM = os.environ.get("RSPR_HOST_SIM", str(ROOT / "target" / "debug" / "host-sim"))
GEOMETRY = ROOT / "host-sim" / "robot-config" / "geometry"

TILT = 20.0 / math.sqrt(2.0)
# Poses (mm, deg) and branches of each robot: central, off-centre, the task box's rotated
# corner (20 deg about [1, 1, 0]), another branch, the base plane (a parallel singularity).
RSPR_CASES = [
    ([0, 0, 160, 0, 0, 0], 0),
    ([10, -5, 165, 5, 0, 0], 0),
    ([20, 20, 150, TILT, TILT, 0], 0),
    ([-20, 20, 170, TILT, TILT, 0], 5),
    ([3, 4, 150, -2, 7, 11], 3),
    ([0, 0, 0, 0, 0, 0], 0),
]
USR_CASES = [
    ([0, 0, 80, 0, 0, 0], 0),
    ([5, -3, 85, 4, 2, 1], 0),
    ([-4, 6, 75, 0, -6, 3], 2),
]
UNREACHABLE = [200, 0, 20, 0, 0, 0]
WRENCH = [7, 7, 7, 0.7, 0.7, 0.7]
TAU = {
    "RSPR": ["f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm"],
    "USR": [f"t_{j}{i}_nm" for j in ("alpha", "beta") for i in (1, 2, 3)],
}


def unsigned_zero(s):
    if s.startswith("-") and all(c in "0." for c in s[1:]):
        return s[1:]
    return s


def fixed9(x):
    """robot_config::units::fixed9."""
    return unsigned_zero(f"{x:.9f}")


def significant(x):
    """robot_config::units::significant: ten significant digits, at most 20 decimals."""
    if x == 0.0:
        return "0"
    if not math.isfinite(x):
        return "inf" if x > 0 else ("-inf" if x < 0 else "NaN")
    decimals = int(min(max(9.0 - math.floor(math.log10(abs(x))), 0.0), 20.0))
    return unsigned_zero(f"{x:.{decimals}f}")


def cli(command, robot, header, rows, extra=()):
    """Runs `host-sim COMMAND --csv` on rows; returns its output rows as dicts."""
    text = io.StringIO()
    w = csv.writer(text)
    w.writerow(header)
    w.writerows(rows)
    args = [HOST_SIM, command, "--csv", *robot_flags(robot), *extra]
    out = subprocess.run(args, input=text.getvalue(), capture_output=True, text=True, check=True)
    return list(csv.DictReader(io.StringIO(out.stdout)))


def robot_flags(robot):
    return ["--robot", "usr"] if robot.kind == "USR" else ["--robot", "rspr"]


POSE = ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg", "branch"]


def robots_and_cases():
    for kind, cases in (("rspr", RSPR_CASES), ("usr", USR_CASES)):
        yield rspr.Robot(kind), cases


def pose_rows(cases):
    return [[repr(float(v)) for v in pose] + [b] for pose, b in cases]


@pytest.fixture(scope="module", autouse=True)
def host_sim_exists():
    if not pathlib.Path(HOST_SIM).is_file():
        pytest.fail(f"no host-sim binary at {HOST_SIM} (build it or set RSPR_HOST_SIM)")


def test_ik_agrees_with_the_cli_to_the_printed_digit():
    for robot, cases in robots_and_cases():
        rows = cli("ik", robot, POSE, pose_rows(cases))
        for (pose, b), row in zip(cases, rows):
            q = robot.ik(pose, branch=b)
            assert row["error"] == ""
            assert [fixed9(v) for v in q] == [row[n] for n in robot.joint_names], (pose, b)


def test_ik_on_many_poses_equals_each_pose():
    robot = rspr.Robot()
    poses = np.array([p for p, b in RSPR_CASES if b == 0])
    many = robot.ik(poses)
    assert many == [robot.ik(p) for p in poses]


def test_ik_branches_gives_every_branch_that_ik_solves():
    robot = rspr.Robot()
    pose = [10, -5, 165, 5, 0, 0]
    all_branches = robot.ik_branches(pose)
    assert sorted(all_branches) == list(range(8))
    for b, q in all_branches.items():
        assert q == robot.ik(pose, branch=b)
    # Distinct branches are distinct solutions of the same pose.
    assert len({tuple(round(v, 6) for v in q) for q in all_branches.values()}) == 8


def test_fk_agrees_with_the_cli_and_inverts_ik():
    """FK of IK's joints, started 0.5 mm and 0.5 deg off the pose (from the central
    configuration the Newton iteration need not reach another branch's pose)."""
    for robot, cases in robots_and_cases():
        solvable = [(p, b) for p, b in cases if p[2] != 0]
        joints = [robot.ik(p, branch=b) for p, b in solvable]
        initial = [[v + 0.5 for v in p] for p, b in solvable]
        header = ["branch", *robot.joint_names, "x0_mm", "y0_mm", "z0_mm", "rx0_deg", "ry0_deg", "rz0_deg"]
        rows = cli(
            "fk",
            robot,
            header,
            [[b, *map(repr, q), *map(repr, x0)] for (p, b), q, x0 in zip(solvable, joints, initial)],
        )
        for (pose, b), q, x0, row in zip(solvable, joints, initial, rows):
            fk = robot.fk(q, branch=b, initial=x0)
            assert row["error"] == ""
            assert [fixed9(v) for v in fk["pose"]] == [row[n] for n in POSE[:6]]
            assert str(fk["iterations"]) == row["iterations"]
            # FK inverts IK: the Newton iteration stops at 1e-12 m / rad; at the edge,
            # 1e-9 mm and deg leaves margin for the mm/deg conversion.
            assert np.allclose(fk["pose"], pose, rtol=0, atol=1e-9), (pose, fk)


def test_jacobian_and_forces_agree_with_the_cli():
    for robot, cases in robots_and_cases():
        regular = [(p, b) for p, b in cases if p[2] != 0]
        rows = cli("jacobian", robot, POSE, pose_rows(regular))
        names = [f"j{i}{k}" for i in range(1, 7) for k in range(1, 7)]
        for (pose, b), row in zip(regular, rows):
            jac = robot.jacobian(pose, branch=b)
            flat = [x for r in jac["j"] for x in r]
            assert [significant(x) for x in flat] == [row[n] for n in names]
            assert significant(jac["inv_cond"]) == row["inv_cond"]
        header = POSE + ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"]
        rows = cli("forces", robot, header, [r + WRENCH for r in pose_rows(regular)])
        for (pose, b), row in zip(regular, rows):
            tau = robot.forces(pose, WRENCH, branch=b)
            assert [significant(x) for x in tau] == [row[n] for n in TAU[robot.kind]], (pose, row)


def test_forces_satisfy_virtual_work():
    """tau . (J t) = s_e . t for any twist t (CONVENTIONS.md, "Forces"), to 1e-9 relative."""
    robot = rspr.Robot()
    rng = np.random.default_rng(7)
    for pose, b in RSPR_CASES[:5]:
        j = np.array(robot.jacobian(pose, branch=b)["j"])
        tau = np.array(robot.forces(pose, WRENCH, branch=b))
        for _ in range(5):
            t = rng.normal(size=6)
            lhs, rhs = tau @ (j @ t), np.dot(WRENCH, t)
            assert abs(lhs - rhs) <= 1e-9 * max(abs(rhs), np.abs(tau).max() * np.abs(j @ t).max())


def gained_words(g, rp_mm):
    """host-sim's `gained` column for one motion."""
    parts = ",".join(f"{x:.6f}" for x in g["twist_scaled"])
    if g["pitch_mm"] is None:
        return f"twist=({parts})|pitch_mm=inf"
    a = ",".join(f"{x:.3f}" for x in g["axis_mm"])
    return f"twist=({parts})|pitch_mm={g['pitch_mm']:.6f}|axis_mm=({a})"


def test_singularity_agrees_with_the_cli():
    for robot, cases in robots_and_cases():
        rows = cli("singularity", robot, POSE, pose_rows(cases))
        serial = "serial_mm" if robot.kind == "RSPR" else "serial_mm2"
        unit = "mm" if robot.kind == "RSPR" else "mm2"
        for (pose, b), row in zip(cases, rows):
            s = robot.singularity(pose, branch=b)
            assert row["error"] == ""
            assert [significant(x) for x in s[serial]] == [row[f"serial{i}_{unit}"] for i in (1, 2, 3)]
            assert [significant(x) for x in s["serial_frac"]] == [row[f"serial{i}_frac"] for i in (1, 2, 3)]
            assert significant(s["parallel_inv_cond"]) == row["parallel_inv_cond"]
            assert str(s["det_sign"]) == row["det_sign"]
            assert s["nearest"] == row["nearest"]
            assert str(s["rank"]) == row["rank"]
            words = " ".join(f"{c['variety']}:{''.join(map(str, c['lines']))}" for c in s["circuits"])
            assert words == row["circuits"]
            assert " ".join(s["configurations"]) == row["configurations"]
            assert (s["complex"] or "") == row["complex"]
            assert " ".join(gained_words(g, robot.rp_mm) for g in s["gained"]) == row["gained"]
            assert s["serial_cases"] == [row[f"serial{i}_case"] for i in (1, 2, 3)]


def test_the_base_plane_is_a_rank_3_singularity():
    """Platform in the base plane: all six lines are horizontal, so they span rank 3 and the
    platform gains the vertical translation and the rotations about x and y (S1)."""
    s = rspr.Robot().singularity([0, 0, 0, 0, 0, 0])
    assert s["rank"] == 3
    assert "S1" in s["configurations"]
    assert len(s["gained"]) == 3
    assert s["parallel_inv_cond"] == 0.0
    # Every gained twist is reciprocal to every line: J~ t = 0 for t = [v; w] (the module
    # gives [v; rp w]); the lines are unit and the twist unit, so 1e-9 is rounding.
    jt = np.array(rspr.Robot().jacobian([0, 0, 0, 0, 0, 0])["jtilde"])
    rp = rspr.Robot().rp_mm / 1000.0
    for g in s["gained"]:
        v = np.array(g["twist_scaled"])
        t = np.concatenate([v[:3], v[3:] / rp])
        assert np.abs(jt @ t).max() < 1e-9, (g, jt @ t)


def test_errors_are_exceptions_with_the_cli_text():
    robot = rspr.Robot()
    rows = cli("ik", robot, POSE, [list(map(str, UNREACHABLE)) + [0]])
    cli_text = rows[0]["error"].split(": ", 1)[1]  # without the CLI's "row N: "
    with pytest.raises(rspr.IkError) as e:
        robot.ik(UNREACHABLE)
    assert str(e.value) == cli_text == "ik: chain 2: no real root (pose out of reach)"
    assert isinstance(e.value, rspr.RsprError) and isinstance(e.value, ValueError)
    with pytest.raises(rspr.InputError, match="branch: 8 is out of range 0..=7"):
        robot.ik([0, 0, 160, 0, 0, 0], branch=8)
    # A NaN is refused with the command line's parser's words for the text "NaN".
    rows = cli("jacobian", robot, POSE, [["0", "0", "NaN", "0", "0", "0", "0"]])
    with pytest.raises(rspr.InputError) as e:
        robot.jacobian([0, 0, float("nan"), 0, 0, 0])
    assert rows[0]["error"] == f"row 1: {e.value}" == 'row 1: z_mm: "NaN" is not a finite number'

    with pytest.raises(rspr.InputError, match="expected 6 numbers, got 5"):
        robot.singularity([0, 0, 160, 0, 0])
    with pytest.raises(rspr.ForcesError, match="parallel singularity"):
        robot.forces([0, 0, 0, 0, 0, 0], WRENCH)
    with pytest.raises(rspr.GeometryError, match="expected \"rspr\" or \"usr\""):
        rspr.Robot("rrps")


def test_many_poses_raise_with_the_row_or_give_none():
    robot = rspr.Robot()
    poses = np.array([[0, 0, 160, 0, 0, 0], UNREACHABLE])
    with pytest.raises(rspr.IkError, match="row 1: ik: chain 2"):
        robot.ik(poses)
    assert robot.ik(poses, errors="none")[1] is None


def test_geometry_files_give_the_built_in_robots():
    for kind in ("rspr", "usr"):
        from_file = rspr.Robot.from_file(GEOMETRY / f"reference-{kind}.toml")
        assert from_file.kind == kind.upper()
        pose = [1, 2, from_file.hc_mm - 3, 2, 1, 0]
        assert from_file.ik(pose) == rspr.Robot(kind).ik(pose)
    with pytest.raises(rspr.GeometryError, match="cannot read"):
        rspr.Robot.from_file(GEOMETRY / "missing.toml")
