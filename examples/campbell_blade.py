"""The Campbell diagram of a rotating blade (reference R2, Wright et al. 1982): a 1 m aluminium
cantilever of a 10 x 2 mm section (lead-lag 25 times stiffer than flap) turned by an angle
driver from 0 to 70 rad/s (g = 0 .. 24). At each speed the steadily rotating, stretched blade
is linearized; the modes are followed by their shapes, so the first flap mode keeps its curve
where it rises through the first lead-lag mode (near g = 18). Prints the frequencies against
R2, the critical speeds of the excitation orders 1 .. 3, and draws ``campbell_blade.png``.
"""

from pathlib import Path

import numpy as np

import flexmbd as fm
from flexmbd.fe import Material, Section

R2_FLAP_1 = {0: 3.5160, 4: 5.5850, 8: 9.2568, 12: 13.1702}


def blade() -> tuple[fm.System, float]:
    material = Material(7.0e10, 0.3, 2700.0)
    width, height = 0.01, 0.002
    system = fm.examples.rotating_beam(
        material, Section.rectangle(width, height), 1.0, 20, geometric_stiffness=True
    )
    flap_stiffness = material.young_modulus * width * height**3 / 12
    return system, np.sqrt(material.density * width * height / flap_stiffness)


def main() -> int:
    system, scale = blade()
    g = np.arange(0.0, 26.0, 2.0)
    diagram = fm.campbell(system, "hub", g / scale, modes=4)
    w_bar = 2 * np.pi * diagram.frequencies * scale
    print("   g   w_bar of the followed modes (flap 1, lead-lag 1, flap 2, flap 3)   R2 flap 1")
    worst = 0.0
    for k, gk in enumerate(g):
        reference = R2_FLAP_1.get(int(gk))
        if reference is not None:
            worst = max(worst, abs(w_bar[k, 0] / reference - 1.0))
        shown = f"{reference:9.4f}" if reference is not None else ""
        print(f"{gk:4.0f}  " + "  ".join(f"{w:8.4f}" for w in w_bar[k]) + f"   {shown}")
    for c in diagram.critical_speeds(orders=(1, 2, 3)):
        print(
            f"order {c['order']:g} meets mode {c['mode'] + 1} at {c['speed']:.2f} rad/s "
            f"({c['frequency']:.3f} Hz)"
        )
    path = Path(__file__).with_name("campbell_blade.png")
    fm.plot_campbell(diagram, path)
    print(f"largest relative difference from R2 (flap 1): {worst:.1e}; written: {path.name}")
    return int(worst > 1e-3)


if __name__ == "__main__":
    raise SystemExit(main())
