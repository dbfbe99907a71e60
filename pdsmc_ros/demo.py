"""``make demo``: the serial circle with PD, SMC and PD-SMC, compared as in Table 4.27."""

from __future__ import annotations

import sys

from .presets import make_run
from .reproduce import LABEL, smc_reading
from .simulator import simulate


def main() -> int:
    print("Serial 3R, circular contour (Tables 4.25-4.28), in-process discrete loop at 10 kHz")
    rows = []
    for controller in ("pd", "smc", "pdsmc"):
        spec = make_run(
            "serial_3r",
            "circle",
            controller,
            smc_model=smc_reading("thesis_fit") if controller == "smc" else None,
        )
        rows.append((controller, simulate(spec).metrics))
    print(f"{'controller':10s} {'contour mean (m)':>17s} {'SD (m)':>11s} {'<= 2e-4 m':>10s} {'max |tau| (N m)':>24s}")
    for controller, m in rows:
        torque = " ".join(f"{t:6.3f}" for t in m.max_torque)
        print(f"{LABEL[controller]:10s} {m.contour_mean:17.4e} {m.contour_sd:11.4e} "
              f"{m.contour_within_pct:9.2f}% {torque:>24s}")
    pd, smc, pdsmc = (m.contour_mean for _, m in rows)
    print(f"PD-SMC: {100 * (pd - pdsmc) / pd:.1f} % smaller mean contour error than PD, "
          f"{100 * (smc - pdsmc) / smc:.1f} % smaller than SMC (thesis: 16.8 % and 24.3 %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
