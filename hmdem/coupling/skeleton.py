"""A Newton step for the pressure-volume iteration from the linearised grain skeleton (issue 3).

The P-V map H of one flow step (digest §6) is: domain pressures p_trial -> Eq. 8 forces
F = C p_trial -> DEM over dt -> grain displacements dx -> domain volume changes dV = D dx ->
implicit pressure solve -> p_calc. Its stiff part is the last link: a liquid-filled domain with
K = 2,000 MPa turns a relative volume change of 1e-6 into 2 kPa, so near the port
dp_calc/dp_trial reaches ~100 (B1, BENCHMARKS.md) in many directions at once, and a secant
model (IQN-ILS) has to discover each of them with an evaluation of the DEM.

Here every link is linearised at t^n instead:

- C: Eq. 8 at the grain positions of t^n (:func:`hmdem.flow.grain_forces.pressure_force_matrix`);
- the grains: dx = S^-1 dF with S = K + m / (c dt^2), K the stiffness of the contact springs
  (k_n along each contact normal, k_s across it at the contact point, each disc with x, y and
  rotation; held degrees of freedom left out) and m / (c dt^2) the inertia of a grain pushed
  from rest for dt (c = 1/2 without damping). Short steps are inertia-bound (dx = F dt^2 / 2m),
  long ones settle on the springs (dx = K^-1 F): the grains of the Huang sample ring at ~0.5 us.
  Contacts sliding at the Coulomb limit get no shear spring: on the B1 checkpoint at 2 ms, 263
  of 2,580 contacts slide; with their shear springs the model's response was half the DEM's,
  without them within 14-22 % on three of four probes (BENCHMARKS.md);
- D: dV/dx of the centre polygons (:meth:`DomainGeometry.volume_gradient`);
- the pressure solve: A dp = -dV / dt, with A the step's implicit matrix (storage V/(K dt) plus
  the conductances of the open pipes).

So J = dH/dp ~ -A^-1 D S^-1 C / dt, and the Newton step on r = H(p) - p, (I - J) dp = r, is
solved as one sparse system in dp and the displacements y = S^-1 C dp:

    [ A        D / dt ] [dp]   [A r]
    [ -C       S      ] [y ] = [ 0 ]

factorised once per attempt (~20 ms for 1,400 discs). Contacts made or lost within the step and
damping are left out: the Newton step is a preconditioner, and the IQN-ILS update built on top
of it (on G(p) = p + dp) corrects what the linear model misses.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu


def skeleton_stiffness(positions: np.ndarray, radii: np.ndarray, pairs: np.ndarray, k_n: float,
                       k_s: float | np.ndarray) -> sp.csr_matrix:
    """Stiffness (3n, 3n) of linear contact springs between discs, degrees of freedom (x, y,
    rotation) per disc. A contact between i and j (normal n from i to j, tangent t = z x n)
    stretches by (u_j - u_i) . n normally and slides by (u_j - u_i) . t - r_i w_i - r_j w_j.
    ``k_s``: one shear stiffness, or one per contact (0 for a contact sliding at its Coulomb limit)."""
    i, j = pairs[:, 0], pairs[:, 1]
    n = positions[j] - positions[i]
    n /= np.linalg.norm(n, axis=1)[:, None]
    t = np.c_[-n[:, 1], n[:, 0]]
    zero = np.zeros(len(pairs))
    # gradient of each spring's stretch over the six dofs (x_i, y_i, w_i, x_j, y_j, w_j)
    normal = np.stack([-n[:, 0], -n[:, 1], zero, n[:, 0], n[:, 1], zero], axis=1)
    shear = np.stack([-t[:, 0], -t[:, 1], -radii[i], t[:, 0], t[:, 1], -radii[j]], axis=1)
    k_s = np.broadcast_to(np.asarray(k_s, float), len(pairs))[:, None, None]
    block = k_n * normal[:, :, None] * normal[:, None, :] + k_s * shear[:, :, None] * shear[:, None, :]
    dofs = np.concatenate([3 * i[:, None] + np.arange(3), 3 * j[:, None] + np.arange(3)], axis=1)
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    size = 3 * len(positions)
    return sp.csr_matrix((block.ravel(), (rows, cols)), shape=(size, size))


class SkeletonNewton:
    """The linearised P-V Newton step of one flow-step attempt (see the module docstring).

    ``flow_matrix``: A over the pressure unknowns; ``to_nodes``: the (n_unknowns, n_domains)
    0/1 matrix summing domains onto unknowns (its transpose spreads unknowns to domains, the
    Dirichlet ones at 0); ``force``: C, (2 n_grains, n_domains); ``volume_gradient``: D,
    (n_domains, 2 n_grains); ``stiffness``: K, (3 n_grains, 3 n_grains); ``masses``,
    ``inertias``: per grain; ``free``: (n_grains, 3), the x, y and spin of each grain that the DEM
    moves; ``inertia_factor``: c.
    """

    def __init__(self, flow_matrix, to_nodes, force, volume_gradient, stiffness, masses, inertias, free, dt,
                 inertia_factor: float = 0.5):
        n_grains = len(masses)
        dof_mass = np.stack([masses, masses, inertias], axis=1).ravel()
        dofs = np.flatnonzero(np.asarray(free, bool).reshape(n_grains, 3))
        # the force and volume maps act on x and y only: column (x_k, y_k) is dof (3k, 3k + 1)
        xy_dofs = (3 * np.arange(n_grains)[:, None] + np.arange(2)).ravel()
        xy_to_dofs = sp.csr_matrix((np.ones(2 * n_grains), (xy_dofs, np.arange(2 * n_grains))),
                                   shape=(3 * n_grains, 2 * n_grains))[dofs]
        stiff = stiffness[dofs][:, dofs] + sp.diags(dof_mass[dofs] / (inertia_factor * dt * dt))
        coupling_v = to_nodes @ volume_gradient @ xy_to_dofs.T / dt
        coupling_f = -(xy_to_dofs @ force @ to_nodes.T)
        system = sp.bmat([[flow_matrix, coupling_v], [coupling_f, stiff]], format="csc")
        # equilibrate: A ~ 1e-11, S ~ 1e8 in SI units. The pattern is symmetric and, scaled, the
        # diagonal dominates: pivoting on it with a minimum-degree ordering of A + A^T factorises
        # in ~17 ms for the Huang sample against ~30 ms with COLAMD and partial pivoting
        scale = 1.0 / np.sqrt(np.abs(system.diagonal()))
        self._scale = scale
        self._lu = splu((sp.diags(scale) @ system @ sp.diags(scale)).tocsc(), permc_spec="MMD_AT_PLUS_A",
                        diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        self._flow_matrix, self._to_nodes = flow_matrix, to_nodes
        self._domains_per_unknown = np.asarray(to_nodes.sum(axis=1)).ravel()
        self.n_unknowns = flow_matrix.shape[0]

    def step(self, residual: np.ndarray) -> np.ndarray:
        """dp per domain solving (I - J) dp = r for the residual r = p_calc - p_trial per domain
        (Dirichlet domains get 0)."""
        to_nodes = self._to_nodes
        r_node = (to_nodes @ residual) / self._domains_per_unknown  # domains sharing an unknown agree
        rhs = np.zeros(len(self._scale))
        rhs[:self.n_unknowns] = self._flow_matrix @ r_node
        solution = self._scale * self._lu.solve(self._scale * rhs)
        return to_nodes.T @ solution[:self.n_unknowns]
