"""Flap frequencies of a rotating cantilever (reference R2, Wright et al. 1982): the blade is
turned at constant speed by an angle driver, the steady, centrifugally stretched state is found
by `flexmbd.equilibrium`, and the motion is linearized about it (`flexmbd.linearize`; see
`flexmbd.examples.rotating_blade_flap_frequencies`). With the geometric stiffness of the
centrifugal tension the flap frequencies rise with the speed; without it they stay at the
non-rotating value.

Nondimensional: w_bar = w sqrt(rho A L^4 / EI), g = W sqrt(rho A L^4 / EI).
"""

import numpy as np

from flexmbd.examples import rotating_blade_flap_frequencies

R2 = {0: (3.5160, 22.0345), 4: (5.5850, 24.2733), 8: (9.2568, 29.9954), 12: (13.1702, 37.6031)}


def main() -> int:
    worst = 0.0
    # Each row as it is computed (flush: also when the output is a pipe or a log file).
    print(
        "   g   w1 (R2)    w1        w2 (R2)    w2        w1 without geometric stiffness",
        flush=True,
    )
    for g, reference in R2.items():
        computed = rotating_blade_flap_frequencies(g, count=2)
        linear = rotating_blade_flap_frequencies(g, geometric_stiffness=False, count=1)
        worst = max(worst, float(np.max(np.abs(computed / np.array(reference) - 1))))
        print(
            f"{g:4d}  {reference[0]:8.4f}  {computed[0]:8.4f}  {reference[1]:8.4f}  "
            f"{computed[1]:8.4f}  {linear[0]:8.4f}",
            flush=True,
        )
    print(f"largest relative difference from R2: {worst:.1e}")
    return int(worst > 1e-3)


if __name__ == "__main__":
    raise SystemExit(main())
