"""
A batch sweep
=============

A TOML scenario describes a pipeline once and a sweep over its options; :func:`pverosion.batch.run_batch`
(or ``pverosion batch scenario.toml``) runs every job on Dask, writes one folder per job and a
results table, and skips completed jobs when run again. Here: two procedural rocks weathered with
three power modifiers.
"""

# %%
import os
import tempfile

import matplotlib.pyplot as plt
import pyvista as pv

from pverosion.batch import parse_scenario, run_batch

QUICK = os.environ.get("PVEROSION_QUICK") == "1"  # set by the documentation build
scenario = parse_scenario(f"""
name = "rocks"
[input]
example = "rock"
subdivisions = {3 if QUICK else 5}
[[stages]]
stage = "weather"
iterations = {30 if QUICK else 150}
[sweep]
"weather.power" = [1.0, 2.0, 3.0]
"input.seed" = [1, 2]
""")
out = tempfile.mkdtemp(prefix="pverosion_batch_")
# serial=True runs the jobs in this process; leave it out to run them on a local Dask cluster,
# or pass scheduler="tcp://host:8786" to use a running one.
report = run_batch(scenario, out, serial=True, progress=False)
for row in report.rows:
    print(f"{row['label']}: {row['status']}, volume change {row['volume_change']:+.4f}")

# %%
fig, ax = plt.subplots(figsize=(5, 3.2), constrained_layout=True)
for seed in (1, 2):
    rows = [r for r in report.rows if r["input.seed"] == seed]
    ax.plot([r["weather.power"] for r in rows], [r["volume_change"] for r in rows], "o-", label=f"rock {seed}")
ax.set(xlabel="power modifier n", ylabel="volume change", title="results.csv")
ax.legend()

# %%
# Every job's final mesh is in its folder: ``jobs/NNNN-<id>/final.vtp``.
plotter = pv.Plotter(shape=(2, 3), window_size=(900, 600))
for i, row in enumerate(report.rows):
    plotter.subplot(i // 3, i % 3)
    plotter.add_text(row["label"], font_size=7)
    plotter.add_mesh(pv.read(report.root / "jobs" / row["folder"] / "final.vtp"), color="tan")
plotter.link_views()
plotter.show()
