"""Polynomials with rational coefficients (:class:`Poly`) and quaternions of them (scalar first:
:func:`qmul`, :func:`qconj`, :func:`qdot`), just what the forward kinematics' polynomial systems of
:mod:`glpma_ros.modes.exact` need; :func:`rational` reads a float as the shortest decimal that reads back as
it.  Exact arithmetic (:class:`fractions.Fraction`), plain Python."""
from __future__ import annotations

import math
from fractions import Fraction
from functools import reduce


class Poly:
    """A polynomial as ``{exponent tuple: Fraction}`` (just what the formulations need)."""

    __slots__ = ("n", "terms")

    def __init__(self, n: int, terms=None):
        self.n = n
        self.terms = {m: c for m, c in (terms or {}).items() if c != 0}

    @classmethod
    def const(cls, n: int, c) -> "Poly":
        return cls(n, {(0,) * n: Fraction(c)})

    @classmethod
    def var(cls, n: int, i: int) -> "Poly":
        return cls(n, {tuple(int(k == i) for k in range(n)): Fraction(1)})

    def _coerce(self, other) -> "Poly":
        return other if isinstance(other, Poly) else Poly.const(self.n, other)

    def __add__(self, other):
        other = self._coerce(other)
        t = dict(self.terms)
        for m, c in other.terms.items():
            t[m] = t.get(m, 0) + c
        return Poly(self.n, t)

    __radd__ = __add__

    def __neg__(self):
        return Poly(self.n, {m: -c for m, c in self.terms.items()})

    def __sub__(self, other):
        return self + (-self._coerce(other))

    def __rsub__(self, other):
        return self._coerce(other) - self

    def __mul__(self, other):
        other = self._coerce(other)
        t = {}
        for m1, c1 in self.terms.items():
            for m2, c2 in other.terms.items():
                m = tuple(a + b for a, b in zip(m1, m2))
                t[m] = t.get(m, 0) + c1 * c2
        return Poly(self.n, t)

    __rmul__ = __mul__

    def to_msolve(self, names) -> str:
        """Integer coefficients (denominators cleared, content removed), expanded, no spaces."""
        if not self.terms:
            return "0"
        lcm = reduce(lambda a, b: a * b // math.gcd(a, b), (c.denominator for c in self.terms.values()), 1)
        ints = {m: int(c * lcm) for m, c in self.terms.items()}
        g = reduce(math.gcd, (abs(v) for v in ints.values()))
        out = []
        for m in sorted(ints, reverse=True):
            c = ints[m] // g
            mono = "*".join(f"{v}^{k}" if k > 1 else v for v, k in zip(names, m) if k)
            if not mono:
                out.append(f"{c:+d}")
            elif c in (1, -1):
                out.append(("+" if c > 0 else "-") + mono)
            else:
                out.append(f"{c:+d}*{mono}")
        s = "".join(out)
        return s[1:] if s.startswith("+") else s


def rational(v: float) -> Fraction:
    """The shortest decimal that reads back as ``v`` (the documented rounding of the input)."""
    return Fraction(repr(float(v)))


def qmul(p, q):
    """The quaternion product ``p q`` (scalar first) of quaternions of polynomials (or numbers)."""
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    return (p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0)


def qconj(p):
    """The conjugate of the quaternion ``p`` (scalar first)."""
    return (p[0], -p[1], -p[2], -p[3])


def qdot(p, q):
    """The dot product of two quaternions (or of two 4-tuples)."""
    return sum(a * b for a, b in zip(p, q))
