"""A satellite slewed by a torque: a rigid bus with two flexible shell solar panels.

The bus (500 kg, a 1 m cube) carries two aluminium panels of 2 x 1 m and 5 mm (flat shells,
6 clamped modes each, first bending frequency about 1 Hz). A bang-bang torque about x turns
the rigid satellite by 30 degrees rest to rest in T s; the panels bend under the angular
acceleration and keep vibrating once the torque stops. For T = 20 s and 10 s and both shell
elements the run reports the slew angle reached, the panel tip deflection (its mean while the
torque is constant against the static deflection of the same panel under the rigid
satellite's inertial load, an independent solution) and the residual vibration after the
slew. Runs in about a second.

    python examples/satellite.py [--plot FILE.png]   (no plot without --plot)
"""

from __future__ import annotations

import argparse

import numpy as np

import flexmbd as fm


def run(duration: float, element: str) -> dict[str, float]:
    example = fm.examples.satellite(duration=duration, element=element)
    result = fm.simulate(
        example.system,
        example.end_time,
        example.step_size,
        output_interval=example.output_interval,
        solver=example.solver,
    )
    bus, panel = example.items["bus"], example.items["panels"][0]
    rotation = result.orientation(bus)
    angle = np.degrees(np.arctan2(rotation[:, 2, 1], rotation[:, 1, 1]))
    tip = result.deflection(panel, example.items["tips"][0])[:, 2]
    t = result.time
    accelerating = (t > 0.1 * duration) & (t < 0.5 * duration)
    return {
        "time": t,
        "tip": tip,
        "angle": float(angle[-1]),
        "peak": float(np.abs(tip).max()),
        "mean": float(tip[accelerating].mean()),
        "static": fm.examples.satellite_quasi_static_tip(example),
        "residual": float(np.abs(tip[t > duration]).max()),
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--plot", default=None)
    args = parser.parse_args()
    runs = {}
    print("slew  element  angle (deg)  tip peak (mm)  mean / static  residual (mm)")
    for duration in (20.0, 10.0):
        for element in ("quad4", "tri3"):
            r = runs[duration, element] = run(duration, element)
            print(f"{duration:4.0f} s  {element:7s}  {r['angle']:11.3f}  {1e3 * r['peak']:13.3f}  "
                  f"{r['mean'] / r['static']:13.4f}  {1e3 * r['residual']:13.3f}")  # fmt: skip
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4))
        for duration in (20.0, 10.0):
            r = runs[duration, "quad4"]
            ax.plot(r["time"], 1e3 * r["tip"], label=f"slew in {duration:.0f} s")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("panel tip deflection (mm)")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
