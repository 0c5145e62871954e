"""The Campbell diagram of an overhung rotor (reference R8): a steel disc (radius 0.15 m,
0.03 m thick) welded to the tip of a nearly massless cantilever shaft (0.4 m, 20 mm, steel
stiffness) that an angle driver spins about its axis from 0 to 600 rad/s. At each speed the
steady rotation is linearized in the shaft's rotating frame; each mode's whirl is measured on
the shaft's nodes and its frequency converted to the fixed frame (forward whirl at
w_rotating + W, backward at w_rotating - W). Prints the whirl frequencies against R8's
determinant, the forward critical speed (the first forward whirl meeting the 1x line)
against R8's, and draws ``campbell_rotor.png``.
"""

from pathlib import Path

import numpy as np

import flexmbd as fm

#: Largest relative difference from R8 accepted (the shaft's own mass, 6e-7 of the disc's,
#: moves the frequencies by 1.5e-7).
TOLERANCE = 1e-6


def analytic_critical_speed(reference: dict[str, float]) -> float:
    """R8's determinant at w = W: (k11 - m W^2)(k22 + (I_p - I_d) W^2) = k12^2, the lowest
    positive root W (rad/s)."""
    m, i_p, i_d = (reference[k] for k in ("mass", "polar inertia", "diametral inertia"))
    k11, k12, k22 = (reference[k] for k in ("k11", "k12", "k22"))
    squares = np.roots([-m * (i_p - i_d), k11 * (i_p - i_d) - m * k22, k11 * k22 - k12**2])
    return float(np.min(np.sqrt(squares[squares.real > 0].real)))


def main() -> int:
    rotor = fm.examples.overhung_rotor()
    speeds = np.linspace(0.0, 600.0, 25)
    diagram = fm.campbell(rotor.system, "spin", speeds, modes=5, frame="fixed")
    labels = diagram.whirl_labels
    print("speed (rad/s)" + "".join(f"  {label or 'no whirl':>9s}" for label in labels))
    for k in range(0, len(speeds), 4):
        w = 2 * np.pi * diagram.frequencies[k]
        print(f"{speeds[k]:13.0f}" + "".join(f"  {v:9.3f}" for v in w) + "   rad/s")
    errors = rotor.check(diagram)
    for name, value in errors.items():
        print(f"{name} from R8: {value:.1e}")
    # The critical speed: refined by a second sweep across the bracket of the first.
    coarse = [c for c in diagram.critical_speeds(orders=(1,)) if c["whirl"] == "forward"][0]
    low = speeds[speeds < coarse["speed"]][-1]
    fine = fm.campbell(
        rotor.system, "spin", np.linspace(low, low + speeds[1], 26), modes=5, frame="fixed"
    )
    critical = [c for c in fine.critical_speeds(orders=(1,)) if c["whirl"] == "forward"][0]
    expected = analytic_critical_speed(rotor.reference)
    difference = abs(critical["speed"] / expected - 1.0)
    print(
        f"forward critical speed {critical['speed']:.4f} rad/s "
        f"(R8 {expected:.4f} rad/s, relative difference {difference:.1e})"
    )
    path = Path(__file__).with_name("campbell_rotor.png")
    fm.plot_campbell(diagram, path, orders=(1,))
    print(f"written: {path.name}")
    return int(max(*errors.values(), difference) > TOLERANCE)


if __name__ == "__main__":
    raise SystemExit(main())
