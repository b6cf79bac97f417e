"""The guards' verdict, the workspace, the synthesis and the RSPR/RRPS comparison of `rspr`
against the command line (`host-sim check`, `workspace`, `synth`, `compare`) and against the
properties the Rust tests state.

The module and the CLI run the same Rust functions, so every number the CLI prints must be
the text of the module's value formatted the CLI's way (`fixed`, `significant`): a printed
figure with 3 to 6 decimals is a comparison to its last digit, and the ten significant
digits of `significant` are one to better than 1e-12 relative for the forces compared here.
"""

import csv
import io
import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import rspr
from test_rspr import GEOMETRY, HOST_SIM, POSE, ROOT, cli, fixed9, significant, unsigned_zero

LIMITS = ROOT / "host-sim" / "robot-config" / "limits" / "reference.toml"
TILT = 20.0 / math.sqrt(2.0)


def fixed(x, decimals):
    """robot_config::units::fixed."""
    return unsigned_zero(f"{x:.{decimals}f}")


def run_cli(*args):
    out = subprocess.run([HOST_SIM, *map(str, args)], capture_output=True, text=True, check=True)
    return out.stdout


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# ---------------------------------------------------------------------------------------
# The guards' verdict

CHECK_CASES = [
    ([0, 0, 160, 0, 0, 0], 0),  # central: ok
    ([20, 20, 150, TILT, TILT, 0], 0),  # the task's rotated corner
    ([0, 0, 0.16, 0, 0, 0], 0),  # a pose typed in metres
    ([200, 0, 20, 0, 0, 0], 0),  # out of reach
    ([24, -24, 172, 0, 0, 24], 0),  # beyond the box and the margin, turned
    ([3, 4, 150, -2, 7, 11], 3),  # another branch
]


def test_check_agrees_with_the_cli():
    robot = rspr.Robot()
    rows = cli("check", robot, POSE, [[repr(float(v)) for v in p] + [b] for p, b in CHECK_CASES])
    ik_rows = cli("ik", robot, POSE, [[repr(float(v)) for v in p] + [b] for p, b in CHECK_CASES])
    severities = set()
    for (pose, b), row, ik_row in zip(CHECK_CASES, rows, ik_rows):
        c = robot.check(pose, branch=b)
        assert row["error"] == ""
        assert str(c["ok"]).lower() == row["ok"], (pose, c, row)
        assert c["severity"] == row["severity"]
        assert ";".join(v["text"] for v in c["violations"]) == row["violations"]
        # The value and limit fields carry the CLI's printed digits (3 decimals, 4 when
        # dimensionless).
        for v in c["violations"]:
            d = 4 if v["unit"] == "" else 3
            assert v["text"].endswith(f":{fixed(v['value'], d)}:{fixed(v['limit'], d)}")
        # The verdict in words is the `guards` column of `ik` (where ik solves the pose).
        if ik_row["error"] == "":
            assert c["verdict"] == ik_row["guards"]
        severities.add(c["severity"])
    # The cases cover a pose without violation and a stop (the test compares something).
    assert {"", "stop"} <= severities


def test_check_on_many_poses_and_a_limits_file(tmp_path):
    robot = rspr.Robot()
    poses = np.array([p for p, b in CHECK_CASES if b == 0])
    assert robot.check(poses) == [robot.check(p) for p in poses]
    # A shorter stroke (a limits file keeps the keys it does not set) makes the central
    # pose's legs (170.88 mm) too long.
    short = tmp_path / "short.toml"
    short.write_text("stroke_max_mm = 170.0\n")
    tight = rspr.Robot(limits=short)
    assert tight.limits_source.endswith("short.toml")
    c = tight.check([0, 0, 160, 0, 0, 0])
    assert not c["ok"] and c["severity"] == "stop"
    assert {v["guard"] for v in c["violations"]} == {"stroke"}
    out = cli("check", tight, POSE, [["0", "0", "160", "0", "0", "0", "0"]], extra=["--limits", str(short)])
    assert out[0]["violations"] == ";".join(v["text"] for v in c["violations"])
    with pytest.raises(rspr.GeometryError, match="cannot read"):
        rspr.Robot(limits=tmp_path / "missing.toml")


def test_a_pose_the_guards_accept_has_its_legs_inside_the_stroke():
    """The property of the Rust guards' tests: no stop-level violation => every leg of the
    inverse kinematics within [stroke_min, stroke_max] (reference limits: 144 .. 210 mm),
    and a leg outside it is a stop, on random poses around the task box
    (seeded), half of them refused (the test would fail on a guard that accepted all)."""
    robot = rspr.Robot()
    rng = np.random.default_rng(11)
    n = 400
    poses = np.column_stack(
        [
            rng.uniform(-40, 40, n),
            rng.uniform(-40, 40, n),
            rng.uniform(120, 200, n),
            rng.uniform(-25, 25, (n, 3)),
        ]
    )
    checks = robot.check(poses)
    accepted = [p for p, c in zip(poses, checks) if c["ok"]]
    assert 0.1 * n < len(accepted) < 0.9 * n, len(accepted)
    for p, c in zip(poses, checks):
        if not c["ok"]:
            continue
        q = robot.ik(p)
        assert all(144.0 <= l <= 210.0 for l in q[:3]), (p, q)
    # And the converse on the stroke: a leg outside the stroke is a stop.
    for p, c in zip(poses, checks):
        try:
            q = robot.ik(p)
        except rspr.IkError:
            assert "reach" in {v["guard"] for v in c["violations"]} and not c["ok"]
            continue
        if any(l < 144.0 or l > 210.0 for l in q[:3]):
            assert not c["ok"] and "stroke" in {v["guard"] for v in c["violations"]}, (p, q, c)


# ---------------------------------------------------------------------------------------
# The workspace

WS = dict(z_mm=(-10.0, 10.0, 10.0), phi_step_deg=45.0, step_mm=2.0, tol_mm=0.01)


def test_workspace_agrees_with_the_cli(tmp_path):
    robot = rspr.Robot()
    w = robot.workspace(**WS)
    out = run_cli(
        "workspace", "--z-mm", "-10,10,10", "--phi-step-deg", 45, "--step-mm", 2, "--tol-mm", 0.01,
        "--out", tmp_path,
    )
    rows = read_csv(tmp_path / "workspace.csv")
    mine = [
        [s["orientation"], *(fixed(x, 6) for x in s["rotation_deg"]), fixed(s["z_mm"], 3), fixed(p, 3), fixed(r, 3)]
        for s in w["sections"]
        for p, r in zip(s["phi_deg"], s["rho_max_mm"])
    ]
    theirs = [list(r.values()) for r in rows]
    assert mine == theirs
    assert len(mine) == 2 * 3 * 8
    t = w["task_box"]
    head = "inside the workspace" if t["inside"] else "NOT inside the workspace"
    assert f"({t['points']} points," in out and f"): {head}" in out
    for v in t["orientation_violations"]:
        assert (v is None) or (f"first failing point {v}" in out)


def test_workspace_boundary_is_admissible_and_settings_are_checked():
    """rho_max is the last admissible radius of the bisection: the pose there is admissible,
    and the scan's radii agree with `admissible` along each ray."""
    robot = rspr.Robot()
    w = robot.workspace(**WS)
    for s in w["sections"]:
        r = s["rotation_deg"]
        for phi, rho in zip(s["phi_deg"], s["rho_max_mm"]):
            if rho <= 0:
                continue
            c, sn = math.cos(math.radians(phi)), math.sin(math.radians(phi))
            assert robot.admissible([rho * c, rho * sn, s["z_mm"], *r]) is None, (s["z_mm"], phi, rho)
            if rho < 150.0:
                # The bisection's inadmissible end lies within tol_mm beyond it.
                beyond = [robot.admissible([x * c, x * sn, s["z_mm"], *r]) for x in np.linspace(rho, rho + WS["tol_mm"], 21)[1:]]
                assert any(b is not None for b in beyond), (s["z_mm"], phi, rho)
    with pytest.raises(rspr.DesignError, match="z_mm: need FROM <= TO"):
        robot.workspace(z_mm=(10, -10, 5))
    with pytest.raises(rspr.DesignError, match="tol_mm: -1 is not a number > 0"):
        robot.workspace(tol_mm=-1)


# ---------------------------------------------------------------------------------------
# The synthesis

SYNTH_FLAGS = ["--e-mm", "20,20,1", "--rb-mm", "80,100,10", "--rp-mm", "50,50,1", "--hc-mm", "150,160,10"]


def test_synth_agrees_with_the_cli(tmp_path):
    found = rspr.synth(e_mm=(20, 20, 1), rb_mm=(80, 100, 10), rp_mm=(50, 50, 1), hc_mm=(150, 160, 10), jobs=1)
    run_cli("synth", *SYNTH_FLAGS, "--jobs", 1, "--out", tmp_path)
    rows = read_csv(tmp_path / "synth.csv")
    assert len(found) == len(rows) == 6
    for c, row in zip(found, rows):
        for name, v in c["dims_mm"].items():
            assert fixed(v, 3) == row[name]
        assert fixed(c["envelope_volume_cm3"], 3) == row["envelope_volume_cm3"]
        assert str(c["admissible"]).lower() == row["admissible"]
        assert (c["rejected"] or "") == row["rejected"]
        assert fixed(c["parallel_inv_cond_min"], 6) == row["parallel_inv_cond_min"]
        assert fixed(c["serial_min"], 6) == row["serial_min"]
        for q, (lo, hi) in c["ranges"].items():
            assert (fixed(lo, 4), fixed(hi, 4)) == (row[f"{q}_min"], row[f"{q}_max"])
    ranked = read_csv(tmp_path / "admissible.csv")
    mine = sorted((c for c in found if c["admissible"]), key=lambda c: c["rank"])
    assert [c["rank"] for c in mine] == list(range(1, len(ranked) + 1))
    for c, row in zip(mine, ranked):
        assert [fixed(v, 1) for v in c["dims_mm"].values()] == [row[n] for n in c["dims_mm"]]


def task_poses(hc_mm):
    """The thesis's task (host-sim/design/tasks/thesis.toml): the 40 x 40 x 20 mm box about
    [0, 0, hc] on a 9 x 9 x 5 grid, platform parallel and rotated 20 deg about [1,1,0]."""
    g = np.array(np.meshgrid(np.linspace(-20, 20, 9), np.linspace(-20, 20, 9), np.linspace(-10, 10, 5))).reshape(3, -1).T
    g[:, 2] += hc_mm
    parallel = np.column_stack([g, np.zeros((len(g), 3))])
    rotated = np.column_stack([g, np.full((len(g), 2), TILT), np.zeros(len(g))])
    return np.vstack([parallel, rotated])


def test_the_reference_rspr_reproduces_its_printed_figure():
    """The reference RSPR misses exactly one bound of the thesis's synthesis: leg 1 needs
    143.75 mm < 144 mm (README, "Design tools"); the leg range the synthesis reports is the
    range of the inverse kinematics over the task poses."""
    [c] = rspr.synth(dims=[20, 90, 50, 160])
    assert not c["admissible"] and c["rank"] is None
    assert "143.75 < 144" in c["rejected"], c["rejected"]
    legs = np.array(rspr.Robot().ik(task_poses(160.0)))[:, :3]
    assert abs(legs.min() - 143.75) < 0.005
    lo, hi = c["ranges"]["l1_mm"]
    assert abs(lo - legs[:, 0].min()) < 1e-9 and abs(hi - legs[:, 0].max()) < 1e-9
    # Many robots at once equal one at a time.
    many = rspr.synth(dims=np.array([[20, 90, 50, 160], [20, 80, 50, 150]]), jobs=1)
    assert many[0] | {"rank": None} == c | {"rank": None}
    with pytest.raises(rspr.InputError, match="l1_mm: not a dimension of the RSPR"):
        rspr.synth(l1_mm=(50, 60, 10))
    with pytest.raises(rspr.DesignError, match="dims row 0: expected 4 dimensions"):
        rspr.synth(dims=[[20, 90, 50]])


# ---------------------------------------------------------------------------------------
# The comparison


def test_compare_agrees_with_the_cli(tmp_path):
    robot = rspr.Robot()
    out = run_cli("compare", "--out", tmp_path)
    rows = read_csv(tmp_path / "compare.csv")
    c = robot.compare()
    assert len(rows) == len(c["s"]) == 101
    for i, row in enumerate(rows):
        assert fixed(c["s"][i], 6) == row["s"]
        assert [fixed(x, 6) for x in c["poses"][i]] == [row[n] for n in POSE[:6]]
        for name in ("rspr", "rrps"):
            tau = c[f"{name}_tau"][i]
            cols = [f"{name}_{k}" for k in ("f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm")]
            assert [significant(x) for x in tau] == [row[k] for k in cols]
    # The reductions table: e = 0, then the robot's e = 20 on both, then RSPR 20 / RRPS 0.
    for label, kw in (("e=0", {}), ("e=20", {"e_mm": 20.0}), ("e=20/0", {"e_mm": 20.0, "rrps_e_mm": 0.0})):
        r = c if not kw else robot.compare(**kw)
        for name, key in (("rotary torque", "rotary_torque"), ("leg force", "leg_force")):
            red = r[key]["reduction"]
            line = f"  {name:<14} {label:<9} {red['peak'] * 100:>7.1f}% {red['mean'] * 100:>8.1f}% {red['peak_to_peak'] * 100:>10.1f}%"
            assert line in out, (line, out)
    # The printed figure: 19.3 % less peak rotary torque at e = 0 (README).
    assert f"{c['rotary_torque']['reduction']['peak'] * 100:.1f}" == "19.3"


def test_compare_readings_are_those_of_the_samples():
    """peak = max |tau|, mean = mean |tau|, peak-to-peak = the largest range of one joint,
    over the samples both robots computed; reduction = 1 - RSPR/RRPS."""
    c = rspr.Robot().compare(samples=41)
    both = [i for i in range(41) if c["rspr_tau"][i] is not None and c["rrps_tau"][i] is not None]
    assert len(both) == 41
    for key, cols in (("rotary_torque", slice(3, 6)), ("leg_force", slice(0, 3))):
        for name in ("rspr", "rrps"):
            t = np.array([c[f"{name}_tau"][i] for i in both])[:, cols]
            r = c[key][name]
            assert r["peak"] == np.abs(t).max()
            assert abs(r["mean"] - np.abs(t).mean()) <= 1e-12 * r["peak"]
            assert r["peak_to_peak"] == (t.max(axis=0) - t.min(axis=0)).max()
        red = c[key]["reduction"]
        assert red["peak"] == 1 - c[key]["rspr"]["peak"] / c[key]["rrps"]["peak"]
    assert c["rspr_peaks"] == list(np.abs(np.array(c["rspr_tau"])).max(axis=0))
    with pytest.raises(rspr.DesignError, match="compare needs an RSPR"):
        rspr.Robot("usr").compare()
    with pytest.raises(rspr.DesignError, match="samples: 1 is below 2"):
        rspr.Robot().compare(samples=1)


# ---------------------------------------------------------------------------------------
# The README's example script


def test_the_example_script_runs_and_writes_its_plot():
    out_dir = ROOT / "target" / "python-example"
    png = out_dir / "synthesis.png"
    if png.exists():
        png.unlink()
    script = ROOT / "host-sim" / "python" / "examples" / "synthesis_scan.py"
    env = dict(os.environ, MPLBACKEND="Agg")
    done = subprocess.run([sys.executable, str(script), str(out_dir)], capture_output=True, text=True, env=env, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert png.stat().st_size > 10_000
    assert "admissible" in done.stdout
