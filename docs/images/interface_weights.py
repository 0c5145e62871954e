"""Draws docs/images/interface-weights.png: the root face of an unevenly meshed tapered link
(Gmsh, tet10), its nodes sized by their area weights, the weighted centroid (the face centre)
and the plain node average, and the principal axes of the interface.

    python docs/images/interface_weights.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from flexmbd.fe import shapes  # noqa: E402
from flexmbd.fe.interface import _FACETS, make_interface  # noqa: E402

mesh = shapes.tapered_link(
    0.3,
    (0.04, 0.02),
    (0.02, 0.01),
    size=0.03,
    order=2,
    size_field="0.004 + 2.0 * (y + 0.02) * (y + 0.02)",
)
root = mesh.node_sets["root"]
face = make_interface(mesh.nodes, mesh.elements, root, name="root")
inside = np.zeros(len(mesh.nodes), dtype=bool)
inside[root] = True
figure, axes = plt.subplots(figsize=(7.5, 4.2))
# The facets of the face (tri6: draw the corner triangle through the mid-edge nodes).
conn = mesh.elements["tet10"]
for local in _FACETS["tet10"][1]:
    cells = conn[:, list(local)]
    for cell in cells[inside[cells].all(axis=1)]:
        ring = [cell[0], cell[3], cell[1], cell[4], cell[2], cell[5], cell[0]]
        xy = mesh.nodes[ring][:, 1:] * 1e3
        axes.plot(xy[:, 0], xy[:, 1], color="0.75", lw=0.6, zorder=1)
yz = mesh.nodes[face.members][:, 1:] * 1e3
w = face.weights
axes.scatter(yz[w > 0, 0], yz[w > 0, 1], s=4e3 * w[w > 0], color="tab:blue", zorder=2,
             label="node, area of its weight")
axes.scatter(yz[w == 0, 0], yz[w == 0, 1], s=6, marker="x", color="0.4", zorder=2,
             label="corner node of a tri6 facet: weight 0")
average = mesh.nodes[root].mean(axis=0)[1:] * 1e3
centroid = face.centroid[1:] * 1e3
axes.plot(*average, marker="P", ms=11, color="tab:red", ls="", zorder=3,
          label=f"node average ({average[0]:.2f}, {average[1]:.2f}) mm")
axes.plot(*centroid, marker="*", ms=15, color="tab:green", ls="", zorder=3,
          label=f"weighted centroid ({abs(centroid[0]):.2f}, {abs(centroid[1]):.2f}) mm")
for k, (name, colour) in enumerate([("x", "tab:purple"), ("y", "tab:orange")]):
    axis = face.principal_axes[1:, k] * 6
    axes.annotate("", xy=centroid + axis, xytext=centroid,
                  arrowprops={"arrowstyle": "->", "color": colour, "lw": 1.6}, zorder=4)
    axes.text(*(centroid + 1.15 * axis), f"{name} (principal)", color=colour, fontsize=8)
axes.set_aspect("equal")
axes.set_xlabel("y (mm)")
axes.set_ylabel("z (mm)")
axes.set_title("Root face of a tapered link (40 x 20 mm, Gmsh tet10, graded in y):\n"
               "area weights put the interface at the face centre", fontsize=10)
axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=8, frameon=False)
figure.tight_layout()
output = Path(__file__).with_name("interface-weights.png")
figure.savefig(output, dpi=110)
print(f"written: {output}")
