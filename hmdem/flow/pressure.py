"""Implicit pressure equation with capillary-threshold front pipes (seed 004 Eqs. 2, 6, 7, 15-17).

Backward Euler in pressure for every unknown domain i:

    (V_i / (K_i dt)) (p_i^{n+1} - p_i^n) + dV_i/dt + sum_j q_ij = q_in,i

with q_ij = G_ij (p_i - p_j) on ordinary pipes (Eq. 1) and, on front pipes from invading side
u to defending side d, q_ud = G max(p_u - p_d + p_c, 0) (Eq. 6). The max() is resolved by an
active-set (semismooth Newton) loop over the blocked set C (digest §5.2 [INTERP]); each pass
solves the symmetric M-matrix system of Eqs. 16-17, where the p_c source enters row u with -G p_c
and row d with +G p_c (digest §5.2 [DERIVED]).

Outflow domains are Dirichlet (p = 0) and are not unknowns. Domains that share a node index are
one unknown: that is how the inlet manifold is expressed (all inflow domains at one pressure).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .ordering import nested_dissection
from .sparse import CsrPattern, SpdSolver

MAX_ACTIVE_SET_PASSES = 40


@dataclass
class PressureSolution:
    pressure: np.ndarray  # per domain, Dirichlet domains at 0
    pipe_flux: np.ndarray  # per flowing pipe, from end a to end b [m^3/s per m]
    blocked: np.ndarray  # per flowing pipe, True if a front pipe is held shut by capillarity
    margin: np.ndarray  # per flowing pipe, orient (p_a - p_b) + p_c (front pipes only, else 0)
    passes: int
    increment: np.ndarray  # p^{n+1} - p^n per domain as solved, before p^n + increment is rounded
    settled: bool = True  # False: the shut pipes cycled or ran out of passes, and their union was held


class PressureSystem:
    """Topology-fixed part of the implicit system: unknown numbering and CSR pattern.

    ``pipe_a``, ``pipe_b``: domain ids at the two ends of each flowing pipe.
    ``node``: unknown index per domain, -1 for Dirichlet (p = 0) domains.
    ``domain_xy``: domain positions, if known, for a nested-dissection ordering of the unknowns.
    Pipes whose two ends map to the same unknown, or both to Dirichlet, carry no flow and must
    not be passed in.
    """

    _floating_key = None  # the open pipes floating_components last labelled (packed bits)

    def __init__(self, pipe_a: np.ndarray, pipe_b: np.ndarray, node: np.ndarray, domain_xy: np.ndarray | None = None):
        self.pipe_a, self.pipe_b, self.node = pipe_a, pipe_b, node
        self.n_unknowns = int(node.max()) + 1 if node.size and node.max() >= 0 else 0
        na, nb = node[pipe_a], node[pipe_b]
        if np.any((na == nb) & (na >= 0)) or np.any((na < 0) & (nb < 0)):
            raise ValueError("pipes joining one unknown to itself or two Dirichlet domains carry no flow")
        self.na, self.nb = na, nb
        self.va, self.vb = na >= 0, nb >= 0
        self.vab = self.va & self.vb
        n = self.n_unknowns
        diag = np.arange(n)
        rows = np.concatenate([diag, na[self.va], nb[self.vb], na[self.vab], nb[self.vab]])
        cols = np.concatenate([diag, na[self.va], nb[self.vb], nb[self.vab], na[self.vab]])
        self.pattern = CsrPattern(rows, cols, n)
        self.domain_is_unknown = node >= 0
        ordering = None
        if domain_xy is not None and n > 0:
            adjacency = self.pattern.matrix(np.ones(len(rows)))
            ordering = nested_dissection(adjacency, self.node_means(domain_xy))
        self.solver = SpdSolver(ordering)

    def node_means(self, per_domain: np.ndarray) -> np.ndarray:
        """Mean of a per-domain quantity (scalar or vector) over the domains of each unknown."""
        m = self.domain_is_unknown
        count = np.bincount(self.node[m], minlength=self.n_unknowns)
        values = per_domain[m].reshape(m.sum(), -1)
        columns = [np.bincount(self.node[m], values[:, k], self.n_unknowns) / count for k in range(values.shape[1])]
        return np.stack(columns, axis=1).reshape((self.n_unknowns,) + per_domain.shape[1:])

    @property
    def to_nodes_matrix(self) -> sp.csr_matrix:
        """:meth:`to_nodes` as a sparse (n_unknowns, n_domains) 0/1 matrix; its transpose is
        :meth:`domain_values`."""
        m = self.domain_is_unknown
        shape = (self.n_unknowns, len(self.node))
        return sp.csr_matrix((np.ones(m.sum()), (self.node[m], np.flatnonzero(m))), shape=shape)

    def to_nodes(self, per_domain: np.ndarray) -> np.ndarray:
        """Sum a per-domain quantity onto the unknowns (Dirichlet domains dropped)."""
        m = self.domain_is_unknown
        return np.bincount(self.node[m], weights=per_domain[m], minlength=self.n_unknowns)

    def matrix(self, storage_node: np.ndarray, g_open: np.ndarray):
        values = np.concatenate([storage_node, g_open[self.va], g_open[self.vb], -g_open[self.vab], -g_open[self.vab]])
        return self.pattern.matrix(values)

    def pipe_source_to_nodes(self, s: np.ndarray, sign_a: float = -1.0) -> np.ndarray:
        """Row contributions of a pipe source s (flux a -> b held fixed): row a gets -s, row b +s.
        ``sign_a=+1`` sums s at both ends instead (the size of the terms in a row)."""
        n = self.n_unknowns
        return np.bincount(self.nb[self.vb], s[self.vb], n) + sign_a * np.bincount(self.na[self.va], s[self.va], n)

    def residual(self, storage_node, source_node, p_old, g_open, orient, entry_pressure):
        """r(x) = source - storage x - sum_j q_ij(p^n + x) in extended precision: the mass defect
        of each unknown for the increment x, used for iterative refinement (mixed precision).

        B - A x in exact arithmetic. In double precision, refinement stalls at ~1e-9 Q in cf1:
        right after an invasion the old fluxes with the new air conductances reach ~1e6 Q, so B
        carries round-off ~1e-10 Q per node, and the air-cluster pressure level is ill-conditioned
        (air conductance / storage ~1e9). With the residual in 80-bit floats, refinement brings
        the per-step mass balance (digest U8) of cf1 from 2e-9 to ~1e-12.
        """
        ext = np.longdouble
        storage_x, source_x = storage_node.astype(ext), source_node.astype(ext)
        p_old_x, g_x = p_old.astype(ext), g_open.astype(ext)
        pc_x = (orient * entry_pressure).astype(ext)

        def r(x):
            x = x.astype(ext)
            p = p_old_x.copy()
            m = self.domain_is_unknown
            p[m] += x[self.node[m]]
            flux = g_x * (p[self.pipe_a] - p[self.pipe_b] + pc_x)
            out = source_x - storage_x * x
            np.add.at(out, self.nb[self.vb], flux[self.vb])
            np.subtract.at(out, self.na[self.va], flux[self.va])
            return out

        return r

    def node_values(self, per_domain: np.ndarray) -> np.ndarray:
        """Pressure of each unknown from a per-domain field (domains sharing a node agree)."""
        out = np.zeros(self.n_unknowns)
        m = self.domain_is_unknown
        out[self.node[m]] = per_domain[m]
        return out

    def domain_values(self, per_node: np.ndarray) -> np.ndarray:
        """Per-domain field from the unknowns; Dirichlet domains get 0 (gauge outflow pressure)."""
        out = np.zeros(len(self.node))
        m = self.domain_is_unknown
        out[m] = per_node[self.node[m]]
        return out

    def solve(
        self,
        storage: np.ndarray,
        p_old: np.ndarray,
        source: np.ndarray,
        conductance: np.ndarray,
        orient: np.ndarray,
        entry_pressure: np.ndarray,
        blocked: np.ndarray,
        hold_blocked: bool = False,
    ) -> PressureSolution:
        """Solve Eqs. 15-17 for p^{n+1}.

        storage: V_i / (K_i dt) per domain; p_old: p^n per domain; source: q_in,i - dV_i/dt per
        domain. conductance: G per flowing pipe (Eq. 1). orient: +1 if end a is the invading side
        of a front pipe, -1 if end b is, 0 for ordinary pipes. entry_pressure: p_c per pipe
        (Eq. 5). blocked: starting guess for C. hold_blocked=True keeps C fixed (used by Eq. 19).

        The unknown is the increment p^{n+1} - p^n, with the right side B - A p^n formed from pipe
        pressure differences. In an air cluster the diagonal of A is ~1e7 times its storage part,
        so working with absolute pressures carries round-off ~1e-16 A_ii p per row that, summed
        over the cluster, broke the per-step mass balance (digest U8) at ~3e-9 in vf. The
        increment is then refined against the extended-precision residual of :meth:`residual`.
        """
        front = orient != 0
        storage_node = self.to_nodes(storage)
        source_node = self.to_nodes(source)
        dp_old = p_old[self.pipe_a] - p_old[self.pipe_b]
        blocked = blocked & front
        seen: set[bytes] = set()
        settled = True
        for passes in range(1, MAX_ACTIVE_SET_PASSES + 1):
            used = blocked
            g_open = np.where(blocked, 0.0, conductance)
            A = self.matrix(storage_node, g_open)
            # B - A p^n from the old flux of each pipe, G (p_a - p_b + orient p_c)
            old_flux = g_open * (dp_old + orient * entry_pressure)
            B = source_node + self.pipe_source_to_nodes(old_flux)
            B_size = np.abs(source_node) + self.pipe_source_to_nodes(np.abs(old_flux), sign_a=1.0)
            residual = self.residual(storage_node, source_node, p_old, g_open, orient, entry_pressure)
            increment = self.domain_values(self.solver.solve(A, B, residual=residual, b_size=B_size, storage=storage_node,
                                                             floating=self.floating_components(g_open),
                                                             offset=self.node_values(p_old)))
            p = p_old + increment
            # p_u - p_d + p_c from p^n + increment in extended precision, as the residual has it:
            # rounded to doubles first (~eps |p|), then multiplied by the huge conductances of a
            # nearly inviscid fluid, fluxes ended up to 1e-7 Q off the solved balance (decisions #80)
            p_exact = p_old.astype(np.longdouble) + increment
            drive = p_exact[self.pipe_a] - p_exact[self.pipe_b] + orient * entry_pressure
            margin = np.where(front, (orient * drive).astype(float), 0.0)
            if hold_blocked:
                break
            new_blocked = front & (margin <= 0.0)
            if np.array_equal(new_blocked, blocked):
                break
            key = np.packbits(new_blocked).tobytes()
            if key in seen or passes == MAX_ACTIVE_SET_PASSES - 1:
                # cycling, or one pass left: the last pass solves with the union of the last two
                # sets held shut (conservative: some shut pipes may have margins > 0, and the next
                # step's Eq. 19 check sees them again), and the solve says it did not settle (#88)
                hold_blocked, settled = True, False
                new_blocked = blocked | new_blocked
            seen.add(key)
            blocked = new_blocked
        flux = (g_open * drive).astype(float)
        return PressureSolution(p, flux, used, margin, passes, increment, settled)

    def floating_components(self, g_open: np.ndarray) -> np.ndarray:
        """Per unknown, a label of its component of open pipes if that component has no open
        pipe to a Dirichlet domain (a shut-in island: only its storage fixes its level), else -1.
        Kept (read-only) while the same pipes are open: the P-V evaluations of a coupled step
        solve over one set of open pipes, and the labelling costs ~0.8 ms on the Huang network."""
        is_open = g_open > 0.0
        key = np.packbits(is_open).tobytes()
        if key != self._floating_key:
            self._floating_key = None  # a labelling cut short leaves nothing to reuse
            self._floating = self._label_floating(is_open)
            self._floating.flags.writeable = False
            self._floating_key = key
        return self._floating

    def _label_floating(self, is_open: np.ndarray) -> np.ndarray:
        n = self.n_unknowns
        inner = self.vab & is_open
        graph = sp.coo_matrix((np.ones(inner.sum()), (self.na[inner], self.nb[inner])), shape=(n, n))
        _, label = connected_components(graph, directed=False)
        to_dirichlet = (self.va != self.vb) & is_open
        grounded_node = np.where(self.va, self.na, self.nb)[to_dirichlet]
        grounded = np.zeros(label.max() + 1 if n else 0, bool)
        grounded[label[grounded_node]] = True
        floating = ~grounded
        new_label = np.cumsum(floating) - 1
        return np.where(floating[label], new_label[label], -1)

    def divergence(self, pipe_flux: np.ndarray) -> np.ndarray:
        """Net pipe outflow of every domain, sum_j q_ij (per domain, Dirichlet ones included)."""
        n = len(self.node)
        return np.bincount(self.pipe_a, weights=pipe_flux, minlength=n) - np.bincount(
            self.pipe_b, weights=pipe_flux, minlength=n
        )
