"""A pendulum on a vertically shaken support: the stability of periodic motions (Floquet).

The support moves as y = a sin(w t). Hanging, the pendulum is stable at every instant of the
shake ("frozen time"), yet shaken at twice its own frequency it grows: parametric resonance.
Upright, it falls at every instant, yet a fast enough shake holds it up (Kapitza's pendulum:
about a^2 w^2 > 2 g L). `fm.floquet` decides both from runs of the model over one period;
the multipliers are checked against those of the linear periodic equation (Mathieu's),
(m L^2 + I) theta_dd + m L (g + y_dd(t)) theta = 0 (upright: -), whose fundamental matrix
scipy integrates, and the smallest amplitude that holds the pendulum upright against
Kapitza's estimate.
"""

import numpy as np

import flexmbd as fm

G, LENGTH = 9.81, 1.0  # (fm.examples.shaken_pendulum's defaults)


def main() -> int:
    own = np.sqrt(G / LENGTH)
    cases = [(0.05, 2 * own, False), (0.05, 3 * own, False)]
    cases += [(a, 60.0, True) for a in (0.03, 0.05, 0.07, 0.09, 0.11)]
    worst, first_stable = 0.0, None
    print(" a (m)   w (rad/s)  position  max |mu|   stable   Mathieu max |mu|")
    for amplitude, rate, upright in cases:
        model = fm.examples.shaken_pendulum(amplitude, rate, upright=upright).compile()
        period = 2 * np.pi / rate
        analysis = fm.floquet(model, fm.State.of_model(model), period, period / 1600)
        expected = fm.examples.shaken_pendulum_multipliers(amplitude, rate, upright=upright)
        found = np.sort_complex(analysis.multipliers)
        worst = max(worst, float(np.max(np.abs(found - np.sort_complex(expected)))))
        position = "upright" if upright else "hanging"
        print(
            f"{amplitude:6.3f} {rate:10.2f}  {position:8s} {np.abs(found).max():9.6f}"
            f"   {analysis.stable!s:6s}  {np.abs(expected).max():9.6f}"
        )
        if upright and analysis.stable and first_stable is None:
            first_stable = amplitude
    kapitza = np.sqrt(2 * G * LENGTH) / 60.0
    print(f"largest difference from Mathieu's multipliers: {worst:.1e}")
    print(f"held upright from a = {first_stable} m (Kapitza's estimate {kapitza:.3f} m)")
    ok = worst < 1e-5 and first_stable is not None and kapitza <= first_stable < kapitza + 0.04
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
