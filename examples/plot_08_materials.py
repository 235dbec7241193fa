"""
Materials from a CT volume and its slices
=========================================

A material field answers "which material, how hard" at any point; every erosion stage divides
its speed by the hardness there. :func:`pverosion.materials_from_volume` builds one from a scan:
material k is where the value exceeds k of the thresholds, and the boundary faces of the
thresholded voxels (coplanar faces merged) are inserted into a C-BSP tree, smaller than the volume
and exact at its voxels. The MR head volume is used when ``../shared/data/HeadMRVolume.mhd``
is present, nested procedural blobs otherwise.
"""

# %%

import matplotlib.pyplot as plt
import numpy as np
import pyvista as pv

import pverosion
from pverosion.examples import data_path

DATA = data_path()  # the real scans ($PVEROSION_DATA, else ../shared/data)
if (DATA / "HeadMRVolume.mhd").exists():
    volume, thresholds = pv.read(DATA / "HeadMRVolume.mhd"), [40, 100, 160]
else:
    x, y, z = np.mgrid[-1:1:40j, -1:1:40j, -1:1:40j]
    blobs = 1.5 - np.sqrt(x**2 + (1.3 * y) ** 2 + z**2) + 0.15 * np.sin(5 * x) * np.cos(4 * z)
    volume = pv.ImageData(dimensions=blobs.shape, spacing=(0.05, 0.05, 0.05))
    volume["value"] = blobs.ravel(order="F")
    thresholds = [0.6, 0.9, 1.2]
field = pverosion.materials_from_volume(volume, thresholds, method="complete", seed=0)
print(f"{field.stats.inserted_faces} coplanar face groups inserted: {field.stats.nodes} nodes, "
      f"height {field.stats.height}, {field.stats.tree_bytes} bytes (volume: {field.stats.volume_bytes})")

# %%
# Sample the field on a regular grid over the volume and show its three middle slices.
slices = pverosion.sample_materials(field, dimensions=(96, 96, 96), bounds=volume.bounds)
nx, ny, nz = slices.dimensions
ids = slices["material_id"].reshape((nx, ny, nz), order="F")
fig, axes = plt.subplots(1, 3, figsize=(10, 3.6), constrained_layout=True)
for ax, (title, cut) in zip(axes, (("x = middle", ids[nx // 2].T), ("y = middle", ids[:, ny // 2].T),
                                   ("z = middle", ids[:, :, nz // 2].T))):
    ax.imshow(cut, origin="lower", cmap="copper_r", vmin=0, vmax=len(thresholds), interpolation="nearest")
    ax.set_title(title)
    ax.set_axis_off()
fig.suptitle("material_id: C-BSP built from the volume")

# %%
# The same field drives erosion: a sphere around the volume weathers faster where it is soft.
ball = pv.Icosphere(radius=0.45 * min(np.subtract(volume.bounds[1::2], volume.bounds[::2])), nsub=4,
                    center=volume.center)
out = pverosion.weather(ball, iterations=20, erodibility=field.erodibility)
plotter = pv.Plotter()
plotter.add_mesh(out, scalars="erosion_depth", cmap="viridis", scalar_bar_args={"title": "erosion depth"})
plotter.show()
