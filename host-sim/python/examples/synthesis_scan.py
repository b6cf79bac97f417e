"""A synthesis scan from Python: the RSPR's rotating-link length rb against its central
height hc (e = 20 mm, rp = 50 mm), every robot evaluated over the thesis's task as
`host-sim synth` evaluates it, and a map of the verdicts with the envelope volume of the
admissible ones.

    python host-sim/python/examples/synthesis_scan.py [OUT_DIR]   # default target/python-example
"""

import pathlib
import sys

import matplotlib.pyplot as plt

import rspr

out_dir = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "target/python-example")
out_dir.mkdir(parents=True, exist_ok=True)

found = rspr.synth(e_mm=(20, 20, 1), rb_mm=(70, 110, 5), rp_mm=(50, 50, 1), hc_mm=(140, 180, 5))

ok = [c for c in found if c["admissible"]]
print(f"{len(ok)} of {len(found)} robots admissible")
for c in sorted(ok, key=lambda c: c["rank"])[:3]:
    d = c["dims_mm"]
    print(f"  rank {c['rank']}: rb {d['rb_mm']:.0f} mm, hc {d['hc_mm']:.0f} mm, {c['envelope_volume_cm3']:.0f} cm^3")

fig, ax = plt.subplots(figsize=(7, 5))
for c in found:
    d = c["dims_mm"]
    if not c["admissible"]:
        ax.plot(d["rb_mm"], d["hc_mm"], "x", color="0.6")
volume = ax.scatter(
    [c["dims_mm"]["rb_mm"] for c in ok],
    [c["dims_mm"]["hc_mm"] for c in ok],
    c=[c["envelope_volume_cm3"] for c in ok],
    s=80,
    cmap="viridis",
)
fig.colorbar(volume, label="envelope volume, cm$^3$ (admissible robots)")
ax.plot(90, 160, "o", mfc="none", mec="red", ms=14, label="the prototype (rb 90, hc 160 mm)")
ax.set(xlabel="rb, mm", ylabel="hc, mm", title="RSPR synthesis over the thesis's task (x: rejected)")
ax.legend(loc="upper left")
fig.savefig(out_dir / "synthesis.png", dpi=100)
print(f"wrote {out_dir / 'synthesis.png'}")
