"""Symbolic LDLᵀ solve for symmetric positive definite systems (the mass matrix).

CasADi's generic `solve` on SX builds a QR factorisation: about 3× the expression size of LDLᵀ
for a dense 21×21 system. Structural zeros are skipped so sparse blocks (e.g. the diagonal
flap-flap block of a chordwise feather) cost nothing.
"""
from __future__ import annotations

import casadi as ca


def _is_zero(expr: ca.SX) -> bool:
    return expr.is_zero() if isinstance(expr, ca.SX) else expr == 0


def ldl_solve(matrix: ca.SX, rhs: ca.SX) -> ca.SX:
    """x with matrix·x = rhs, for a symmetric positive definite `matrix` (no pivoting)."""
    n = matrix.size1()
    lower = [[ca.SX(0)] * n for _ in range(n)]
    diag = [ca.SX(0)] * n
    for i in range(n):
        for j in range(i):
            value = matrix[i, j]
            for k in range(j):
                if not (_is_zero(lower[i][k]) or _is_zero(lower[j][k])):
                    value = value - lower[i][k] * lower[j][k] * diag[k]
            lower[i][j] = ca.SX(0) if _is_zero(value) else value / diag[j]
        value = matrix[i, i]
        for k in range(i):
            if not _is_zero(lower[i][k]):
                value = value - lower[i][k] ** 2 * diag[k]
        diag[i] = value
    forward = [ca.SX(0)] * n
    for i in range(n):
        value = rhs[i]
        for k in range(i):
            if not _is_zero(lower[i][k]):
                value = value - lower[i][k] * forward[k]
        forward[i] = value
    solution = [ca.SX(0)] * n
    for i in reversed(range(n)):
        value = forward[i] / diag[i]
        for k in range(i + 1, n):
            if not _is_zero(lower[k][i]):
                value = value - lower[k][i] * solution[k]
        solution[i] = value
    return ca.vertcat(*solution)
