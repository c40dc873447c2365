"""Cable friction in the disk holes: capstan tension loss with stick/slip.

Each cable of the generated model is ONE tendon (spatial, or the native path's), so MuJoCo
transmits one uniform tension T along it (actuator force plus the tendon's own
spring/damper). A real cable loses tension at every hole it slides through: over a hole
where it turns by the wrap angle β, the capstan relation (Euler–Eytelwein) bounds the
tension ratio of the two pieces,

    e^(−μβ) ≤ T_distal / T_proximal ≤ e^(+μβ),

the lower bound reached while the cable is reeled in (slides toward the motor), the upper
one while it pays out, anything between while it sticks. This module adds that physics to
a compiled model through the passive-force callback (``passive``), without touching the
model:

* **Pieces** (``cable_kernels.cable_pieces``): the length, direction and gradient w.r.t. the
  local joint velocities of every piece between two holes, from MuJoCo's kinematics of the
  step (on the native cable path its hook has computed them just before, in the same callback).
* **Stick/slip** (Dahl model, normalised): per hole a state z ∈ [−1, 1] with
  dz/ds = (1 − z·sgn ds)/δ over the cable's sliding distance s through the hole (the
  change of its length beyond the hole); the piece ratio is e^(μβz). It is integrated
  exactly (z → sgn + (z − sgn)e^(−|Δs|/δ)) from the positions at each evaluation, so the
  state is rate-independent, idempotent under repeated ``mj_forward`` and unconditionally
  stable. δ (``presliding``) is the sliding distance over which friction builds up after
  a reversal: the stick band, a numerical regularisation of ideal Coulomb stick.
* **Force** (``cable_kernels.friction_forces``): MuJoCo already applies −T_mj·∂l/∂q for the
  uniform tension; the callback adds −Σ_i (T_i − T_mj)·∂l_i/∂q over the pieces, with
  T_i = T_mj·Π_{holes before i} e^(μβz).

μ = 0 installs nothing: the model runs exactly as without this module. The settings are
``model.friction_options.CableFrictionConfig``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model.friction_options import CableFrictionConfig
from . import passive
from .cable_routing import CablePieces, CableRouting, cable_routing


class CableFriction:
    """Capstan friction with stick/slip on the cables of one (model, data) pair.

    Made by :func:`install_cable_friction`; holds the per-hole states (its data's runtime
    points the kernel at them). ``active`` is False when μ = 0 (nothing was installed).
    ``anchor_ratio()`` is each cable's anchor-to-motor tension ratio at the last evaluation
    (1 without friction).
    """

    def __init__(self, routing: CableRouting, config: CableFrictionConfig,
                 runtime: passive.PassiveRuntime | None) -> None:
        self.config = config
        self.routing = routing
        self.runtime = runtime
        n_cables, n_pieces = routing.n_cables, routing.n_pieces
        self.z = np.zeros(n_pieces)  # stick/slip state of the hole before each piece
        self.s_prev = np.zeros(n_pieces)
        self.initialised = np.zeros(n_cables, dtype=np.bool_)
        self.piece_tension = np.zeros(n_pieces)
        self.wrap = np.zeros(n_pieces)  # β of the hole before each piece (rad)
        self.tension = np.zeros(n_cables)
        self.active = runtime is not None

    @property
    def pieces(self) -> CablePieces | None:
        """The pieces the kernel read at the last evaluation (its data's scratch)."""
        return None if self.runtime is None else self.runtime.pieces

    @property
    def error(self) -> BaseException | None:
        """The first error the passive callback met in this hook (None: none)."""
        return None if self.runtime is None else self.runtime.error("friction")

    def anchor_ratio(self) -> np.ndarray:
        """(C,) anchor / motor tension of each cable at the last evaluation (1: no loss)."""
        r = self.routing
        out = np.ones(r.n_cables)
        if not self.active:
            return out
        last = self.piece_tension[r.cable_end - 1]
        np.divide(last, self.tension, out=out, where=self.tension > 1e-9)  # (the same quotients, no masked copies)
        return out

    def wraps(self) -> np.ndarray:
        """(C,) total wrap angle (rad) of each cable over its holes at the last evaluation."""
        r = self.routing
        return np.array([self.wrap[a:b].sum() for a, b in zip(r.cable_start, r.cable_end, strict=True)])

    def reset(self) -> None:
        """Forget the stick/slip history (the next evaluation starts from z = 0)."""
        self.z[:] = 0.0
        self.initialised[:] = False

    def uninstall(self) -> None:
        """Stop acting on this data (its other hooks, e.g. the native cable path, stay)."""
        if self.runtime is not None:
            self.runtime.set(friction=0)

    def check(self) -> None:
        """Raise the first error the passive callback met (a C callback cannot raise itself)."""
        error = self.error
        if error is not None and not isinstance(error, Exception):
            raise error  # an interrupt delivered inside the Python fallback callback
        if error is not None:
            raise RuntimeError(f"cable friction failed in the passive callback: {error!r}") from error


def install_cable_friction(model: Any, data: Any, config: CableFrictionConfig,
                           tendon_ids: np.ndarray | None = None) -> CableFriction:
    """Attach cable friction to ``data`` of ``model``; returns its handle.

    With μ = 0 nothing is registered (the model runs exactly as before) and the handle
    reports anchor ratios of 1. The stick/slip state starts neutral (z = 0) at the first
    evaluation. On a data of the native cable path (``cable_path.NativeCables.make_data``)
    friction reads the pieces its native hook computed in the same callback (``tendon_ids``
    is then the native path's); otherwise ``tendon_ids`` (default: every arm cable) selects
    the spatial tendons.
    """
    runtime = passive.runtime_of(data)
    if runtime is None and passive.native_owner(model) is not None:
        raise ValueError("cable friction: a data of a native-cable model must come from NativeCables.make_data")
    routing = runtime.routing if runtime is not None else cable_routing(model, tendon_ids)
    if config.mu <= 0.0:
        return CableFriction(routing, config, None)
    if runtime is None:
        runtime = passive.attach(model, data, routing)
    handle = CableFriction(routing, config, runtime)
    runtime.bind(z=handle.z, s_prev=handle.s_prev, initialised=handle.initialised, tension=handle.tension,
                 piece_tension=handle.piece_tension, wrap=handle.wrap)
    runtime.set(mu=config.mu, presliding=config.presliding, base_hole=int(config.base_hole),
                fwdact=int(runtime.sources["act_ids"].size > 0), compute_pieces=int(not runtime.row["native"][0]),
                err_friction=0, friction=1)
    runtime.errors.pop("friction", None)
    return handle
