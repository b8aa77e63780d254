"""ZMP preview control of the cart-table model (Kajita et al., ICRA 2003).

The centre of mass moves at a constant height z_c; along one horizontal axis its state is
x = (position, velocity, acceleration), driven by the jerk u, and the ZMP is
p = position - z_c / g * acceleration (the cart-table / linear inverted pendulum model). The
optimal jerk minimises sum Q (p - p_ref)^2 + R u^2 knowing the next N ZMP references:
u_k = -K x_k + sum_j f_j p_ref[k + j], with K and f_j from the discrete Riccati equation.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_discrete_are

GRAVITY_MPS2 = 9.81


class ZmpPreviewController:
    """Preview controller for both horizontal axes at once (they are decoupled and identical).

    Args:
        com_height_m: z_c of the cart-table model.
        dt_s: control period.
        preview_s: preview horizon; 1.5-2 s is enough for the gains to fade (Kajita 2003).
        zmp_weight: Q, weight of the ZMP tracking error.
        jerk_weight: R, weight of the jerk.
    """

    def __init__(self, com_height_m: float, dt_s: float, preview_s: float = 1.6,
                 zmp_weight: float = 1.0, jerk_weight: float = 1e-6):
        if com_height_m <= 0 or dt_s <= 0 or preview_s < dt_s:
            raise ValueError("ZmpPreviewController needs com_height_m > 0, dt_s > 0 and "
                             f"preview_s >= dt_s; got {com_height_m}, {dt_s}, {preview_s}")
        self.dt_s = dt_s
        self.horizon = round(preview_s / dt_s)
        a = np.array([[1.0, dt_s, dt_s**2 / 2.0], [0.0, 1.0, dt_s], [0.0, 0.0, 1.0]])
        b = np.array([[dt_s**3 / 6.0], [dt_s**2 / 2.0], [dt_s]])
        c = np.array([[1.0, 0.0, -com_height_m / GRAVITY_MPS2]])
        p = solve_discrete_are(a, b, zmp_weight * c.T @ c, np.array([[jerk_weight]]))
        gain_den = jerk_weight + (b.T @ p @ b).item()
        self._feedback = (b.T @ p @ a / gain_den).ravel()              # K
        closed_loop_t = (a - b @ self._feedback[None, :]).T
        preview = np.empty(self.horizon)
        column = zmp_weight * c.T                                   # ((A - BK)^T)^(j-1) C^T Q
        for j in range(self.horizon):
            preview[j] = (b.T @ column).item() / gain_den
            column = closed_loop_t @ column
        self._preview_gains = preview                               # f_1 .. f_N
        self._a, self._b, self._c = a, b, c.ravel()
        self.state = np.zeros((3, 2))                               # rows pos/vel/acc, cols x/y

    def reset(self, com_xy) -> None:
        """Put the CoM at rest at ``com_xy``."""
        self.state[:] = 0.0
        self.state[0] = com_xy

    def translate(self, shift_xy) -> None:
        """Move the CoM's position by ``shift_xy`` (velocity and acceleration unchanged)."""
        self.state[0] += shift_xy

    def step(self, zmp_reference: np.ndarray) -> np.ndarray:
        """Advance one period given the ZMP references of the next N periods, shape (N, 2).

        Returns the new CoM position (2,).
        """
        jerk = -self._feedback @ self.state + self._preview_gains @ zmp_reference
        self.state = self._a @ self.state + self._b @ jerk[None, :]
        return self.state[0].copy()

    @property
    def zmp(self) -> np.ndarray:
        """The model's ZMP now, (2,)."""
        return self._c @ self.state
