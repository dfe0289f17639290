"""Quaternion helpers on components.

Every function takes and returns quaternions as tuples of components ``(w, x, y, z)``
(scalar first, Hamilton convention, body-to-space when used as an attitude). Each component
is a Python float or a numpy array of any batch shape; all components of one argument share
that shape. Writing the algebra component by component lets one implementation serve a single
state (plain floats: no numpy call overhead) and a batch (arrays: one vectorised op per line).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import compiled_form, elementwise, jitable, scalar_form

__all__ = [
    "sqrt",
    "maximum",
    "select",
    "every",
    "power",
    "expm1",
    "atan2",
    "atan_kernel",
    "sincos",
    "two_sum",
    "reduce_pio2",
    "sin_kernel",
    "cos_kernel",
    "SINCOS_LIMIT",
    "quat_multiply",
    "quat_rate",
    "quat_conjugate",
    "quat_normalize",
    "quat_rotate",
    "quat_from_axis_angle",
    "quat_angle",
    "quat_from_two_vectors",
    "quat_to_euler_zxz",
    "quat_random",
    "quat_from_uniforms",
]


@jitable
def maximum(a, b):
    """The larger of two floats (``max``) or the elementwise larger of arrays (``np.maximum``)."""
    return max(a, b) if isinstance(a, float) else np.maximum(a, b)


@jitable
def power(x, p):
    """``x^p`` for a whole ``p >= 1`` (a float) by repeated products: the same bits on floats,
    arrays and in compiled code (``**`` may differ in the last bit between libm and numpy)."""
    r = x
    k = 1.0
    while k < p:
        r = r * x
        k += 1.0
    return r


@jitable
def select(cond, a, b):
    """``a`` where ``cond`` else ``b``: a conditional for one state (``cond`` a bool), ``np.where``
    for a batch (``cond`` a boolean array)."""
    if isinstance(cond, bool):
        return a if cond else b
    return _select_arrays(cond, a, b)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _select_arrays(cond, a, b):
    return np.where(cond, a, b)


@scalar_form(select)
def _select_one(cond, a, b):
    return a if cond else b


@jitable
def every(cond):
    """``cond`` for one state (a bool); for a batch (a boolean array) whether it holds for all."""
    if isinstance(cond, bool):
        return cond
    return _all_arrays(cond)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _all_arrays(cond):
    return bool(cond.all())


@scalar_form(every)
def _every_one(cond):
    return cond


@jitable
def expm1(x):
    """``exp(x) - 1`` with libm's bits for floats, arrays and compiled code (numpy's SIMD
    ``expm1`` differs from libm's in the last bit for many arguments)."""
    if isinstance(x, float):
        return math.expm1(x)
    return _expm1_arrays(x)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _expm1_arrays(x):
    return np.vectorize(math.expm1, otypes=[np.float64])(x)


@jitable
def sqrt(x):
    """Square root of a float or an array, with the same bits either way (IEEE sqrt is
    correctly rounded; ``x ** 0.5`` is libm ``pow`` for a float but SIMD sqrt for an array)."""
    return math.sqrt(x) if isinstance(x, float) else np.sqrt(x)


# fdlibm's atan (Sun Microsystems, 1993; s_atan.c): the breakpoints of its argument reduction,
# atan of each reduced interval's centre as a head and tail, and the odd polynomial's
# coefficients aT[0..10] (|error| < 1 ulp on the reduced interval).
_ATAN_HI = (
    4.63647609000806093515e-01,
    7.85398163397448278999e-01,
    9.82793723247329054082e-01,
    1.57079632679489655800e00,
)
_ATAN_LO = (
    2.26987774529616870924e-17,
    3.06161699786838301793e-17,
    1.39033110312309984516e-17,
    6.12323399573676603587e-17,
)
_PI = 3.14159265358979311600e00
_PI_LO = 1.22464679914735317720e-16  # pi - _PI
_PIO2 = 1.57079632679489655800e00
_HUGE = 1.152921504606846976e18  # 2^60


@jitable
def atan_kernel(r):
    """``atan(r) - r`` split as fdlibm's reduced-interval polynomial: returns ``r * (s1 + s2)``
    for ``|r| <= 7/16`` (floats or arrays; pure arithmetic)."""
    z = r * r
    w = z * z
    s1 = z * (
        3.33333333333329318027e-01
        + w
        * (
            1.42857142725034663711e-01
            + w
            * (
                9.09088713343650656196e-02
                + w
                * (
                    6.66107313738753120669e-02
                    + w * (4.97687799461593236017e-02 + w * 1.62858201153657823623e-02)
                )
            )
        )
    )
    s2 = w * (
        -1.99999999998764832476e-01
        + w
        * (
            -1.11111104054623557880e-01
            + w
            * (
                -7.69187620504482999495e-02
                + w * (-5.83357013379057348645e-02 + w * -3.65315727442169155270e-02)
            )
        )
    )
    return r * (s1 + s2)


@jitable
def atan2(y, x):
    """``atan2(y, x)`` in ``[-pi, pi]`` of floats or arrays, from IEEE arithmetic alone.

    Why not libm or numpy: numpy's array ``arctan2`` (SIMD) and libm's ``atan2`` (what Python's
    ``math`` and numba call) differ in the last bit for some arguments, and the single env
    (floats), the numpy batch and the compiled kernel must compute the same bits. This is
    fdlibm's algorithm (``e_atan2.c``, ``s_atan.c``): the ratio ``t = |y| / |x|``, reduced
    to ``|r| <= 7/16`` on one of five intervals, an odd polynomial, then the quadrant. Only
    ``+ - * /`` and comparisons, so floats, arrays and compiled code give the same result
    (within 1 ulp of glibc's correctly rounded ``atan2``; tested). Signed zeros and
    infinities follow C's ``atan2``; a NaN argument gives NaN.
    """
    if isinstance(y, float):
        if x != x or y != y:
            return x + y
        ay = -y if y < 0.0 else y
        ax = -x if x < 0.0 else x
        if ax == 0.0:
            t = math.inf if ay > 0.0 else 0.0
        elif ay == math.inf and ax == math.inf:
            t = 1.0
        else:
            t = ay / ax
        if t < 0.4375:
            z = t - atan_kernel(t)
        else:
            if t < 0.6875:
                k, r = 0, (2.0 * t - 1.0) / (2.0 + t)
            elif t < 1.1875:
                k, r = 1, (t - 1.0) / (t + 1.0)
            elif t < 2.4375:
                k, r = 2, (t - 1.5) / (1.0 + 1.5 * t)
            else:
                k, r = 3, -1.0 / t
            z = _ATAN_HI[k] - ((atan_kernel(r) - _ATAN_LO[k]) - r)
        if t > _HUGE:  # |y| > 2^60 |x|: pi/2 whatever the sign of x (as fdlibm)
            z = _PIO2
        elif x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0):
            z = _PI - (z - _PI_LO)
        if y < 0.0 or (y == 0.0 and math.copysign(1.0, y) < 0.0):
            return -z
        return z
    out = _atan2_loop(y, x)  # one compiled pass where numba runs (the same bits)
    return _atan2_arrays(y, x) if out is None else out[0]


_atan2_loop = elementwise(atan2, 2, 1)


@compiled_form(atan2)
def _atan2_selects(y, x):
    """:func:`atan2` compiled: every branch a selection (the same operations per argument, so
    the same bits; one division for the reduction, its numerator and denominator selected),
    which keeps a batch loop in SIMD registers and never mispredicts."""
    ay = select(y < 0.0, -y, y)  # (not abs: -0.0 stays -0.0, as in the float form)
    ax = select(x < 0.0, -x, x)
    t = select(
        ax == 0.0,
        select(ay > 0.0, math.inf, 0.0),
        select((ay == math.inf) & (ax == math.inf), 1.0, ay / ax),
    )
    small = t < 0.4375
    k0 = t < 0.6875
    k1 = t < 1.1875
    k2 = t < 2.4375
    # the reduced argument r = num / den on the interval of t (fdlibm's four, or t itself)
    num = select(
        small, t, select(k0, 2.0 * t - 1.0, select(k1, t - 1.0, select(k2, t - 1.5, -1.0)))
    )
    den = select(small, 1.0, select(k0, 2.0 + t, select(k1, t + 1.0, select(k2, 1.0 + 1.5 * t, t))))
    r = select(small, t, num / den)
    hi = select(k0, _ATAN_HI[0], select(k1, _ATAN_HI[1], select(k2, _ATAN_HI[2], _ATAN_HI[3])))
    lo = select(k0, _ATAN_LO[0], select(k1, _ATAN_LO[1], select(k2, _ATAN_LO[2], _ATAN_LO[3])))
    poly = atan_kernel(r)
    z = select(small, r - poly, hi - ((poly - lo) - r))
    z = select(t > _HUGE, _PIO2, select(math.copysign(1.0, x) < 0.0, _PI - (z - _PI_LO), z))
    z = select(math.copysign(1.0, y) < 0.0, -z, z)
    return select((x != x) | (y != y), x + y, z)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _atan2_arrays(y, x):
    """:func:`atan2`'s branches as selections on arrays (the same operations per element)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ay, ax = np.abs(y), np.abs(x)
        t = np.where(
            ax == 0.0,
            np.where(ay > 0.0, np.inf, 0.0),
            np.where((ay == np.inf) & (ax == np.inf), 1.0, ay / ax),
        )
        small = t < 0.4375
        k = np.where(t < 0.6875, 0, np.where(t < 1.1875, 1, np.where(t < 2.4375, 2, 3)))
        r = np.where(
            small,
            t,
            np.where(
                k == 0,
                (2.0 * t - 1.0) / (2.0 + t),
                np.where(
                    k == 1,
                    (t - 1.0) / (t + 1.0),
                    np.where(k == 2, (t - 1.5) / (1.0 + 1.5 * t), -1.0 / t),
                ),
            ),
        )
        poly = atan_kernel(r)
        hi, lo = np.asarray(_ATAN_HI)[k], np.asarray(_ATAN_LO)[k]
        z = np.where(small, r - poly, hi - ((poly - lo) - r))
        z = np.where(t > _HUGE, _PIO2, np.where(np.signbit(x), _PI - (z - _PI_LO), z))
        z = np.where(np.signbit(y), -z, z)
        return np.where(np.isnan(x) | np.isnan(y), x + y, z)


# sin and cos of one argument together, from IEEE arithmetic alone: FreeBSD's/musl's algorithm
# (msun k_sin.c, k_cos.c, e_rem_pio2.c; Sun Microsystems, 1993; the rewrite of __kernel_cos by
# Bruce Evans, 2008). pi/2 in 33-bit pieces and their tails, 2/pi, and the kernels'
# polynomial coefficients (|error| < 1 ulp on [-pi/4, pi/4]).
_INVPIO2 = 6.36619772367581382433e-01
_PIO2_1, _PIO2_1T = 1.57079632673412561417e00, 6.07710050650619224932e-11
_PIO2_2, _PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21
_PIO2_3, _PIO2_3T = 2.02226624871116645580e-21, 8.47842766036889956997e-32
_TOINT = 6755399441055744.0  # 1.5 * 2^52: x + _TOINT - _TOINT rounds x to an integer
_S = (
    -1.66666666666666324348e-01,
    8.33333333332248946124e-03,
    -1.98412698298579493134e-04,
    2.75573137070700676789e-06,
    -2.50507602534068634195e-08,
    1.58969099521155010221e-10,
)
_C = (
    4.16666666666666019037e-02,
    -1.38888888888741095749e-03,
    2.48015872894767294178e-05,
    -2.75573143513906633035e-07,
    2.08757232129817482790e-09,
    -1.13596475577881948265e-11,
)
SINCOS_LIMIT = 1647099.0  # |x| < 2^20 pi/2: the reduction's n fits 20 bits (exact products)
_NO_REDUCTION = 0.785  # below pi/4 the reduction gives (0, x, 0.0) exactly: floats skip it


@jitable
def two_sum(a, b):
    """``(s, e)`` with ``s = fl(a + b)`` and ``a + b = s + e`` exactly (Knuth's TwoSum: no
    condition on the magnitudes, no branch)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@jitable
def reduce_pio2(x):
    """``(n, y0, y1)``: ``x = n pi/2 + y0 + y1`` with ``|y0 + y1| <= pi/4`` and ``y1`` the tail
    of ``y0`` (``n`` a float), for ``|x| < SINCOS_LIMIT``: Cody and Waite's reduction with
    pi/2 in three 33-bit pieces (each product ``n p_k`` exact for ``n < 2^20``) and a tail, the
    differences' rounding errors kept (TwoSum), so ``y0 + y1`` carries about 100 bits of the
    reduced argument whatever the cancellation (msun takes its second and third rounds only
    where the first cancels; here every argument takes the same operations)."""
    fn = x * _INVPIO2 + _TOINT - _TOINT
    r = x - fn * _PIO2_1  # exact: fn < 2^20, _PIO2_1 has 33 bits, and Sterbenz
    r, e2 = two_sum(r, -(fn * _PIO2_2))
    r, e3 = two_sum(r, -(fn * _PIO2_3))
    c = (e2 + e3) - fn * _PIO2_3T
    y0 = r + c
    return fn, y0, (r - y0) + c


@jitable
def sin_kernel(x, y):
    """``sin(x + y)`` for ``|x + y| <= pi/4``, ``y`` the tail of ``x`` (msun ``__kernel_sin``)."""
    z = x * x
    w = z * z
    r = _S[1] + z * (_S[2] + z * _S[3]) + z * w * (_S[4] + z * _S[5])
    v = z * x
    return x - ((z * (0.5 * y - v * r) - y) - v * _S[0])


@jitable
def cos_kernel(x, y):
    """``cos(x + y)`` for ``|x + y| <= pi/4``, ``y`` the tail of ``x`` (msun ``__kernel_cos``)."""
    z = x * x
    w = z * z
    r = z * (_C[0] + z * (_C[1] + z * _C[2])) + w * w * (_C[3] + z * (_C[4] + z * _C[5]))
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + (z * r - x * y))


@jitable
def sincos(x):
    """``(sin x, cos x)`` of a float or an array, from IEEE arithmetic alone.

    Why not libm or numpy: compiled code can keep a loop of arithmetic in SIMD registers but
    not a loop that calls libm, and a batch loop must give the bits the single env computes on
    floats; this is msun's algorithm (:func:`reduce_pio2`, :func:`sin_kernel`,
    :func:`cos_kernel`, then the quadrant), so floats, arrays and compiled code give the same
    bits, within 1 ulp of the exact values (tested against mpmath; equal to glibc's correctly
    rounded results for most arguments). ``|x| >= SINCOS_LIMIT`` (about 1.6e6 rad, a rotation
    far beyond any step of these systems), infinities and NaN give NaN: the step then reports
    a numerical failure, never a wrong angle.
    """
    if isinstance(x, float):
        if not (-SINCOS_LIMIT < x < SINCOS_LIMIT):
            return math.nan, math.nan
        if x == 0.0:  # sin keeps the sign of zero (the reduction's sum would not)
            return x, 1.0
        if -_NO_REDUCTION < x < _NO_REDUCTION:  # n = 0, y0 = x, y1 = 0: the reduction's own result
            return sin_kernel(x, 0.0), cos_kernel(x, 0.0)
        fn, y0, y1 = reduce_pio2(x)
        s, c = sin_kernel(y0, y1), cos_kernel(y0, y1)
        n = int(fn) & 3
        if n == 0:
            return s, c
        if n == 1:
            return c, -s
        if n == 2:
            return -s, -c
        return -c, s
    out = _sincos_loop(x)  # one compiled pass where numba runs (the same bits)
    return _sincos_arrays(x) if out is None else out


@compiled_form(sincos)
def _sincos_selects(x):
    """:func:`sincos` compiled: the quadrant and the range check as selections (the same
    operations per argument, so the same bits), which keeps a batch loop in SIMD registers."""
    ok = (x > -SINCOS_LIMIT) & (x < SINCOS_LIMIT)
    fn, y0, y1 = reduce_pio2(select(ok, x, 0.0))
    s, c = sin_kernel(y0, y1), cos_kernel(y0, y1)
    n = int(fn) & 3
    odd = (n & 1) != 0
    sa = select(odd, c, s)
    ca = select(odd, s, c)
    sa = select((n & 2) != 0, -sa, sa)
    ca = select(((n + 1) & 2) != 0, -ca, ca)
    return select(ok, select(x == 0.0, x, sa), math.nan), select(ok, ca, math.nan)


_sincos_loop = elementwise(sincos, 1, 2)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _sincos_arrays(x):
    """:func:`sincos`'s branches as selections on arrays (the same operations per element)."""
    ok = (x > -SINCOS_LIMIT) & (x < SINCOS_LIMIT)
    fn, y0, y1 = reduce_pio2(np.where(ok, x, 0.0))
    s, c = sin_kernel(y0, y1), cos_kernel(y0, y1)
    n = fn.astype(np.int64) & 3
    odd = (n & 1) != 0
    sa, ca = np.where(odd, c, s), np.where(odd, s, c)
    sa = np.where((n & 2) != 0, -sa, sa)
    ca = np.where(((n + 1) & 2) != 0, -ca, ca)
    return np.where(ok, np.where(x == 0.0, x, sa), np.nan), np.where(ok, ca, np.nan)


@jitable
def quat_multiply(p, q):
    """Hamilton product ``p * q`` of two quaternions given as ``(w, x, y, z)`` components."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


@jitable
def quat_rate(q, w):
    """``dq/dt = q * (0, Omega) / 2``: the attitude's rate under the body angular velocity
    ``w = Omega`` (the kinematics of every system that carries a quaternion)."""
    qw, qx, qy, qz = q
    h1, h2, h3 = 0.5 * w[0], 0.5 * w[1], 0.5 * w[2]
    return (
        -qx * h1 - qy * h2 - qz * h3,
        qw * h1 + qy * h3 - qz * h2,
        qw * h2 - qx * h3 + qz * h1,
        qw * h3 + qx * h2 - qy * h1,
    )


@jitable
def quat_conjugate(q):
    """Conjugate (the inverse, for a unit quaternion)."""
    w, x, y, z = q
    return (w, -x, -y, -z)


@jitable
def quat_normalize(q):
    """Project onto the unit sphere (non-geometric integrators drift off it, docs/physics.md §4).

    A quaternion whose squared norm overflowed or vanished has no direction left: the result
    is NaN, so the environment's non-finite check ends the episode instead of carrying on
    with a zero "rotation"."""
    w, x, y, z = q
    if (
        isinstance(w, float)
        and isinstance(x, float)
        and isinstance(y, float)
        and isinstance(z, float)
    ):
        n2 = w * w + x * x + y * y + z * z
        if not 0.0 < n2 < math.inf:  # overflowed or collapsed: no rotation left to project
            return (math.nan, math.nan, math.nan, math.nan)
        inv = 1.0 / math.sqrt(n2)
    else:
        with np.errstate(
            over="ignore"
        ):  # (an overflow is handled: NaN, as on floats, not a warning)
            n2 = w * w + x * x + y * y + z * z
        inv = _inverse_norm_arrays(n2)
    return (w * inv, x * inv, y * inv, z * inv)


@compiled_form(quat_normalize)
def _quat_normalize_selects(q):
    """:func:`quat_normalize` compiled: the NaN of a collapsed quaternion selected, not branched
    to (the same bits)."""
    w, x, y, z = q
    n2 = w * w + x * x + y * y + z * z
    inv = select((0.0 < n2) & (n2 < math.inf), 1.0 / math.sqrt(n2), math.nan)
    return (w * inv, x * inv, y * inv, z * inv)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _inverse_norm_arrays(n2):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((n2 > 0.0) & (n2 < np.inf), 1.0 / np.sqrt(n2), np.nan)


@jitable
def quat_rotate(q, v):
    """Rotate the vector ``v = (vx, vy, vz)`` by the unit quaternion ``q``: ``R(q) v``."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 (q_vec x v); v' = v + w t + q_vec x t  (the two-cross-product form: 15 mul, 15 add)
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


def quat_from_axis_angle(axis, angle):
    """Unit quaternion of a rotation by ``angle`` (rad) about the unit vector ``axis``."""
    half = 0.5 * np.asarray(angle, dtype=float)
    s = np.sin(half)
    ax, ay, az = axis
    return (np.cos(half), ax * s, ay * s, az * s)


@jitable
def quat_angle(q):
    """Rotation angle in ``[0, pi]`` of a unit quaternion (``q`` and ``-q`` give the same).

    Uses ``2 atan2(|v|, |w|)``, which stays accurate near 0 and pi where ``acos`` does not.
    """
    w, x, y, z = q
    return 2.0 * atan2(sqrt(x * x + y * y + z * z), abs(w))


@jitable
def quat_from_two_vectors(a, b):
    """A rotation taking the unit vector ``a`` to the unit vector ``b`` (the shortest one when
    ``a . b >= 0``).

    ``q ~ (1 + a.b, a x b)`` loses accuracy as ``a`` approaches ``-b`` (``1 + a.b`` cancels). For
    ``a . b < 0`` the rotation is built as the short turn from ``a`` to ``-b`` followed by a half
    turn about an axis ``p`` normal to ``b``: ``q = (0, p) * q(a -> -b)``, accurate everywhere.
    """
    ax, ay, az = a
    bx, by, bz = b
    dot = ax * bx + ay * by + az * bz
    if isinstance(dot, float):
        if dot >= 0.0:
            return _short_turn(a, b, dot)
        return quat_multiply((0.0,) + _normal_axis(b), _short_turn(a, (-bx, -by, -bz), -dot))
    return _two_vectors_arrays(a, b, dot)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _two_vectors_arrays(a, b, dot):
    bx, by, bz = b
    with np.errstate(
        divide="ignore", invalid="ignore"
    ):  # each branch is kept only where it is valid
        direct = _short_turn(a, b, dot)
        flipped = quat_multiply(
            (0.0 * dot,) + _normal_axis(b), _short_turn(a, (-bx, -by, -bz), -dot)
        )
    return tuple(np.where(dot >= 0.0, d, f) for d, f in zip(direct, flipped))


@jitable
def _short_turn(a, b, dot):
    """``normalize(1 + a.b, a x b)`` for ``a . b >= 0`` (no cancellation there)."""
    ax, ay, az = a
    bx, by, bz = b
    return quat_normalize((1.0 + dot, ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx))


@jitable
def _normal_axis(b):
    """A unit vector normal to the unit vector ``b``: ``b x e``, ``e`` the axis least aligned."""
    bx, by, bz = b
    if isinstance(bx, float):
        if abs(bx) < 0.9:
            v = (0.0, bz, -by)  # b x e_x
        else:
            v = (-bz, 0.0, bx)  # b x e_y
    else:
        v = _normal_axis_arrays(b)
    n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _normal_axis_arrays(b):
    bx, by, bz = b
    use_x = np.abs(bx) < 0.9
    return np.where(use_x, 0.0, -bz), np.where(use_x, bz, 0.0), np.where(use_x, -by, bx)


@jitable
def quat_to_euler_zxz(q):
    """Euler angles ``(phi, theta, psi)`` [rad] of ``R(q) = Rz(phi) Rx(theta) Rz(psi)``.

    The classical angles of the top (precession, nutation, spin; [T 3.62]; [MR 15.6]).
    ``theta`` in ``[0, pi]`` comes from ``atan2`` (accurate near the poles); at ``theta = 0`` or
    ``pi`` only ``phi + psi`` (or ``phi - psi``) is defined and ``psi`` is set to 0 there.
    For output only: never integrate them.
    """
    w, x, y, z = q
    r13 = 2.0 * (x * z + w * y)
    r23 = 2.0 * (y * z - w * x)
    r31 = 2.0 * (x * z - w * y)
    r32 = 2.0 * (y * z + w * x)
    r33 = 1.0 - 2.0 * (x * x + y * y)
    r11 = 1.0 - 2.0 * (y * y + z * z)
    r21 = 2.0 * (x * y + w * z)
    sin_t = sqrt(r13 * r13 + r23 * r23)
    theta = atan2(sin_t, r33)
    pole = sin_t < 1e-12
    # at a pole R = Rz(phi +- psi): take psi = 0, phi from the first column
    phi = select(pole, atan2(r21, r11), atan2(r13, -r23))
    psi = select(pole, 0.0 * sin_t, atan2(r31, r32))
    return phi, theta, psi


def quat_random(rng: np.random.Generator, shape=()):
    """Uniformly distributed unit quaternions (Shoemake's method), as component arrays."""
    return quat_from_uniforms(*rng.random((3,) + tuple(shape)))


@jitable
def quat_from_uniforms(u1, u2, u3):
    """Shoemake's map from three uniforms on [0, 1) to a uniformly distributed unit quaternion."""
    a = np.sqrt(1.0 - u1)
    b = np.sqrt(u1)
    return (
        a * np.sin(2.0 * np.pi * u2),
        a * np.cos(2.0 * np.pi * u2),
        b * np.sin(2.0 * np.pi * u3),
        b * np.cos(2.0 * np.pi * u3),
    )
