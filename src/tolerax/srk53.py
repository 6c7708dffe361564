"""SRK53: an explicit Runge-Kutta method whose stability region is fitted to the full planetary
stage's lightly damped fast modes (`tolerax.solve.SOLVERS["SRK53"]`, `tolerax.solve.FAST_STAGE`)."""

from typing import Callable, ClassVar

import diffrax
import numpy as np


class SRK53(diffrax.AbstractERK):
    """An explicit Runge-Kutta method of 3rd order in 5 evaluations a step (FSAL) whose stability
    region is fitted to lightly damped fast modes: the full planetary stage's mesh and bearing
    modes, 7-19 kHz at 3.3-8 % of critical damping in the developing rattle (the slower ones,
    1-7 kHz, down to 0.5 %; `benchmarks/stability_region.py` computes the spectrum).

    Its stability polynomial is `1 + z + z^2/2 + z^3/6 + g4 z^4 + g5 z^5` with `(g4, g5) =
    (0.029692, 0.005774)`, chosen to reach farthest along the rays of 3.5-12 % damping (and the
    imaginary axis up to a third of that): |h lambda| <= 4.15 there, 0.83 per evaluation against
    Bosh3's 1.92 / 3 = 0.64 and RK4's 2.89 / 4 = 0.72. The tableau realises it with the four
    3rd-order conditions exact and three of the four 4th-order error terms zero (the fourth,
    `g4 - 1/24`, is the price of the wider region): principal error norm 0.012 against Bosh3's
    0.042. The embedded 2nd-order estimate uses the step's end (the next step's first
    evaluation) and is scaled so that its leading term equals Bosh3's (`-z^3/48` on `y' = lambda y`):
    a tolerance means about what it means for Bosh3. 3rd-order Hermite interpolation for saves.
    Coefficients from `benchmarks/stability_region.py` (which also checks them); run by diffrax's
    explicit Runge-Kutta machinery. It pays only where the fast modes are damped: on the
    imaginary axis its first limit is |h lambda| = 2.0 (0.40 per evaluation, below Bosh3's 0.58;
    2.2, 2.4, 2.6 at 1, 2, 3 % damping), so a scene whose fastest mode is nearly undamped is
    better served by Bosh3."""

    tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
        a_lower=(
            np.array([0.3460608045359518]),
            np.array([-0.39809683661668177, 0.945544135199833]),
            np.array([0.3415227195051164, 0.1208988793562382, 0.3911794545715382]),
            np.array([0.1774916599842346, 0.40322619254440534, 0.0683326098714273, 0.25998015839414146]),
            np.array([0.1234734783260992, 0.3809135327707099, 0.2106542561450066, 0.11144883687302648, 0.17350989588515775]),
        ),
        b_sol=np.array([0.1234734783260992, 0.3809135327707099, 0.2106542561450066, 0.11144883687302648, 0.17350989588515775, 0.0]),
        b_error=np.array([-0.04795646531642149, 0.009103371350003508, 0.04230875117499141, 0.09278855997611822,
                          0.1019280002671631, -0.19817221745185465]),
        c=np.array([0.3460608045359518, 0.5474472985831513, 0.8536010534328928, 0.9090306207942087, 1.0]),
    )
    interpolation_cls: ClassVar[Callable[..., diffrax.ThirdOrderHermitePolynomialInterpolation]] = (
        diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
    )

    def order(self, terms):
        del terms
        return 3
