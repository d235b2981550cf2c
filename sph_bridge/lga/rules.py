"""FHP-II theory: the rule set written as sets of channels, the collision table read back from
the bit-parallel kernel, and the lattice-gas transport coefficients (seed 003 Eqs. 5-6; digest
§1.2-1.3, claims C1-C3).
"""

from __future__ import annotations

import math
import numpy as np

from .automaton import collide

STATES = 128  # seven Boolean channels per node
VELOCITIES = np.array([(0.0, 0.0)] + [(math.cos(math.pi * k / 3), math.sin(math.pi * k / 3)) for k in range(6)])
SOUND_SPEED = math.sqrt(3.0 / 7.0)  # seed 003 §5
REST_DENSITY = 1.0  # particles per node in every run of seed 003 (d = 1/7 per channel)


def channels(state: int) -> frozenset[int]:
    return frozenset(k for k in range(7) if state >> k & 1)


def state_of(chs) -> int:
    return sum(1 << k for k in chs)


def _turn(k: int, by: int) -> int:
    return (k - 1 + by) % 6 + 1


def reference_outcomes(state: int) -> dict[int, float]:
    """The FHP-II rules R1-R4 of digest §1.2 applied to one node as sets: {outcome: probability}."""
    chs = channels(state)
    moving, rest = chs - {0}, 0 in chs
    if len(moving) == 2:
        a, b = sorted(moving)
        if b == _turn(a, 3):  # R1/R2: head-on pair (rest particle a spectator)
            keep = {0} if rest else set()
            return {state_of(keep | {_turn(a, 1), _turn(a, 4)}): 0.5,
                    state_of(keep | {_turn(a, -1), _turn(a, 2)}): 0.5}
        if not rest:  # R4 reverse: two at 120 degrees -> rest + the one between them
            for k in range(1, 7):
                if moving == {_turn(k, -1), _turn(k, 1)}:
                    return {state_of({0, k}): 1.0}
    if len(moving) == 3 and not rest and moving in ({1, 3, 5}, {2, 4, 6}):  # R3
        return {state_of({1, 2, 3, 4, 5, 6} - moving): 1.0}
    if len(moving) == 1 and rest:  # R4: rest + one moving -> two at 120 degrees
        (k,) = moving
        return {state_of({_turn(k, -1), _turn(k, 1)}): 1.0}
    return {state: 1.0}


def kernel_outcomes() -> list[dict[int, float]]:
    """The collision table of :func:`sph_bridge.lga.automaton.collide`: all 128 input states
    through the bit-parallel kernel with chirality 0 and 1 (probability 1/2 each)."""
    table = [dict() for _ in range(STATES)]
    for chirality in (np.uint64(0), np.uint64(0xFFFFFFFFFFFFFFFF)):
        for half in range(2):
            words = [np.uint64(0)] * 7
            for b in range(64):
                s = 64 * half + b
                for k in range(7):
                    if s >> k & 1:
                        words[k] |= np.uint64(1) << np.uint64(b)
            out = collide(*words, chirality)
            for b in range(64):
                s = 64 * half + b
                o = sum(1 << k for k in range(7) if int(out[k]) >> b & 1)
                table[s][o] = table[s].get(o, 0.0) + 0.5
    return table


def conserves(state: int, outcome: int) -> bool:
    """Particle number and momentum (in exact integer half units) equal before and after."""
    def invariants(s):
        chs = channels(s)
        return (len(chs), sum(round(2 * VELOCITIES[k][0]) for k in chs),
                sum(round(2 * VELOCITIES[k][1] / math.sin(math.pi / 3)) for k in chs))
    return invariants(state) == invariants(outcome)


def boltzmann_viscosity(table: list[dict[int, float]], d: float) -> float:
    """Kinematic viscosity of a collision table in the Boltzmann (molecular chaos) approximation
    at occupation ``d`` per channel: the linearised collision operator's eigenvalue lambda on
    the shear mode c_x c_y gives nu = -1/(4 lambda) - 1/8 (digest §1.2 [XCHK]; the -1/8 is the
    lattice's propagation correction)."""
    omega = np.zeros((7, 7))
    for s, outcomes in enumerate(table):
        occupied = np.array([s >> k & 1 for k in range(7)], dtype=float)
        weight = d ** occupied.sum() * (1 - d) ** (7 - occupied.sum())
        for o, prob in outcomes.items():
            change = np.array([o >> k & 1 for k in range(7)], dtype=float) - occupied
            omega += prob * weight * np.outer(change, (occupied - d) / (d * (1 - d)))
    shear = VELOCITIES[:, 0] * VELOCITIES[:, 1]
    lam = shear @ omega @ shear / (shear @ shear)
    return -1.0 / (4.0 * lam) - 0.125


def viscosity(rho: float = REST_DENSITY) -> float:
    """Seed 003 Eq. 6: nu = 1/(28 d (1-d)^3 (1 - 4d/7)) - 1/8 with d = rho/7 (0.307279 at rho = 1)."""
    d = rho / 7.0
    return 1.0 / (28.0 * d * (1 - d) ** 3 * (1 - 4 * d / 7)) - 0.125


def galilean_factor(rho: float = REST_DENSITY) -> float:
    """Seed 003 Eq. 5: g(rho) = (7/12)(2 rho - 7)/(rho - 7) (35/72 at rho = 1)."""
    return 7.0 / 12.0 * (2 * rho - 7) / (rho - 7)
