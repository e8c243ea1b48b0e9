"""Flow compensation of foaming filaments: the paper's polynomials of nozzle temperature.

Foaming filaments expand more the hotter they are printed, so the extruded volume must
shrink with temperature to keep the bead width. The paper (Materials and Methods,
"Foaming Filament Expansion Compensation Details") fits, for a nozzle temperature ``t``
in degC, the flow in percent sent by ``M221 S<F>``:

    F_PLA(t) = 100 (8.35479e-6 t^3 - 5.37075e-3 t^2 + 1.13374 t - 77.814)
    F_TPU(t) = 100 (3.09637e-4 t^2 - 1.38401e-1 t + 15.9560)

Over the printed range 190-225 degC F_PLA falls from about 102 % to 55 % and F_TPU
from about 84 % to 49 %. ``flow_model = "none"`` keeps 100 %.
"""

from __future__ import annotations

import numpy as np

PLA_COEFFICIENTS = (8.35479e-6, -5.37075e-3, 1.13374, -77.814)
TPU_COEFFICIENTS = (3.09637e-4, -1.38401e-1, 15.9560)


def f_pla(t: float | np.ndarray) -> float | np.ndarray:
    """Flow of foaming LW-PLA at nozzle temperature ``t`` (degC), percent."""
    return 100.0 * np.polyval(PLA_COEFFICIENTS, t)


def f_tpu(t: float | np.ndarray) -> float | np.ndarray:
    """Flow of foaming varioShore TPU at nozzle temperature ``t`` (degC), percent."""
    return 100.0 * np.polyval(TPU_COEFFICIENTS, t)


def flow_percent(model: str, t: float | np.ndarray) -> float | np.ndarray:
    """Flow in percent for ``model`` ("none", "pla" or "tpu") at temperature ``t`` (degC)."""
    if model == "pla":
        return f_pla(t)
    if model == "tpu":
        return f_tpu(t)
    return np.full_like(np.asarray(t, dtype=float), 100.0)[()]
