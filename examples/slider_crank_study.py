"""A design study of the flexible slider-crank (reference R4): the rod's diameter and the
crank speed against the largest midpoint deflection of the rod and its largest bending
stress, on a Dask LocalCluster of two worker processes.

Each case writes its results file into ``slider_crank_study/cases``; the gathered dataset
is ``slider_crank_study/study.nc``. Running the script again reuses the cases done. From the
command line the same kind of study is ``flexmbd sweep`` (see ``docs/studies.md``).

The bending stress of the solid circular rod is sigma = M (d / 2) / I = 32 M / (pi d^3).
At d = 6 mm and 150 rad/s the deflection is the reference's 4.658e-3 m (within 1 %).
"""

from pathlib import Path

import numpy as np

import flexmbd as fm

FOLDER = Path(__file__).with_name("slider_crank_study")


def main() -> int:
    study = fm.Study(
        fm.examples.flexible_slider_crank,
        {"rod_diameter": [5e-3, 6e-3, 8e-3], "crank_speed": [100.0, 150.0]},
        outputs={
            "deflection": "max-abs(deflection:rod:5[y])",
            "bending moment": "max(stress:rod[bending])",
        },
        folder=FOLDER,
    )
    print(study)
    data = study.run(workers=2)
    diameter = data["rod_diameter"].values
    data["bending stress"] = 32 * data["bending moment"] / (np.pi * diameter**3)
    print(f"{'d (mm)':>7} {'w (rad/s)':>10} {'max |v_mid| (mm)':>17} {'max sigma_b (MPa)':>18}")
    for k in range(data.sizes["case"]):
        print(
            f"{1e3 * diameter[k]:7.1f} {data['crank_speed'].values[k]:10.0f} "
            f"{1e3 * data['deflection'].values[k]:17.3f} "
            f"{1e-6 * data['bending stress'].values[k]:18.1f}"
        )
    reference = data.where(
        (data["rod_diameter"] == 6e-3) & (data["crank_speed"] == 150.0), drop=True
    )
    error = abs(float(reference["deflection"].values[0]) / 4.658e-3 - 1.0)
    print(f"d = 6 mm, 150 rad/s: relative error of the deflection against R4 {error:.2e}")
    failed = int(np.sum(data["status"].values != "complete"))
    return 0 if failed == 0 and error < 0.01 else 1


if __name__ == "__main__":
    raise SystemExit(main())
