r"""Decimal numbers in a byte buffer to float64, vectorised and correctly rounded.

:func:`parse_decimals` converts many cells of one buffer at once, each given by its
``[start, end)`` byte span, to the float64 nearest to the decimal written (what Python's
``float`` gives), with whole-array numpy operations instead of a call per cell. It is
the number parser of the fast path of the strict CSV readers
(:mod:`odmd_bench.inputs.table`).

A cell in the common form ``[-]digits[.digits]`` (at most 16 digits before the point, 24
after it, a value below 2**64 once the point is dropped) is converted here:

1. its integer and fraction digits are gathered right-aligned into 8-byte words and each
   word's eight digits combined into one integer by multiply-and-shift steps on all the
   words at once ("SWAR": a byte that is no digit is found on the way);
2. the digits make one integer ``w`` below 2**64, and the number is ``w / 10**f`` with
   ``f`` fraction digits. In x87 extended precision (numpy's ``longdouble`` where it has
   a 64-bit significand) ``w`` and ``10**f`` (``f <= 27``) are exact, so the quotient is
   the exact value rounded once to 64 bits. Rounding that to the 53 bits of a float64
   gives the correctly rounded float64 except where the 64-bit value is exactly halfway
   between two float64 (the 11 bits below a float64's last are ``10000000000``): those
   few cells, and every cell in another form (an exponent, a ``+`` sign, more digits),
   are marked for Python's ``float``.

Where ``longdouble`` has no 64-bit significand (it is float64 on Windows and macOS on
ARM, a 113-bit software type on Linux on ARM) only the cells
that plain float64 division rounds right (``w < 2**53``, ``f <= 22``: both operands
exact) are converted here, the rest marked. Either way a converted value is bit for bit
what ``float`` gives the cell; the tests compare the two on millions of cells.
"""

from __future__ import annotations

import functools
import sys

import numpy as np
from numpy.lib.stride_tricks import as_strided, sliding_window_view

#: Digits before the decimal point converted here (two 8-byte words; one word first,
#: the cells with more digits in a second pass).
INT_DIGITS = 16
#: Digits after the decimal point converted here (three 8-byte words).
FRACTION_DIGITS = 24

_U = np.uint64
_ZERO = _U(0x3030303030303030)  # "00000000"
_NINE_UP = _U(0x7676767676767676)  # a lane plus this reaches 0x80 from 10 up
_HIGH = _U(0x8080808080808080)
# _KEEP[k]: the last k bytes of a little-endian word (its k highest lanes), for k = 0..8;
# _KEEP3[k]: the last k bytes of three words, k = 0..24.
_KEEP = np.array([0] + [((1 << 64) - 1) << (8 * (8 - k)) & ((1 << 64) - 1) for k in range(1, 9)], dtype=_U)
_KEEP3 = np.array(
    [[_KEEP[min(max(k - 8 * (2 - j), 0), 8)] for j in range(3)] for k in range(FRACTION_DIGITS + 1)], dtype=_U
)
# The multiply-and-shift steps of eight ASCII digits to their value ("SWAR"): pairs of
# digits, then fours, then all eight.
_SWAR = (
    (_U(10 * 2**8 + 1), _U(8), _U(0x00FF00FF00FF00FF)),
    (_U(100 * 2**16 + 1), _U(16), _U(0x0000FFFF0000FFFF)),
    (_U(10000 * 2**32 + 1), _U(32), None),
)
_POW10_U = np.array([10**k if 10**k < 2**64 else 0 for k in range(FRACTION_DIGITS + 1)], dtype=_U)
_POW10_F = np.array([10.0**k for k in range(FRACTION_DIGITS + 1)])
#: The words are read little-endian (a byte's lane is its place in memory): elsewhere no
#: cell is converted here, and every one goes to ``float``.
LITTLE_ENDIAN = sys.byteorder == "little"
_EXTENDED = np.finfo(np.longdouble).nmant == 63 and np.dtype(np.longdouble).itemsize == 16
_POW10_L = np.array([10**k for k in range(FRACTION_DIGITS + 1)], dtype=np.longdouble)
# Exact in 64 bits (10**k = 2**k * 5**k, 5**24 < 2**64) where numpy made them so, and
# the processor divides to 64 bits (its x87 precision not set lower).
_EXTENDED = (
    _EXTENDED
    and all(int(p) == 10**k for k, p in enumerate(_POW10_L))
    and int(np.array([2**64 - 1], dtype=_U).astype(np.longdouble)[0] / _POW10_L[0]) == 2**64 - 1
)
#: Whether the extended-precision path is used (module state so that tests can turn it off).
use_extended = bool(_EXTENDED)


def _digits(words: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Each word's kept lanes as the value of 8 decimal digits, and the words with a lane that is no digit.

    Args:
        words: (n, k) uint64 of ASCII bytes (changed in place).
        keep: (n, k) or (n,) lane masks: the lanes that are not kept count as "0".

    Returns:
        ``(values, bad)``: (n, k) uint64 (``words`` itself), and (n,) bool where a word
        has a kept lane that is no digit, or None where none has.
    """
    x = words
    x ^= _ZERO
    x &= keep
    # A lane of 10 or more gets its high bit set (a lane of 0x8a or more carries into the
    # next lane, of the same word and so of the same cell: the cell is refused anyway).
    t = x + _NINE_UP
    t |= x
    bad = None
    if np.bitwise_or.reduce(t, axis=None) & _HIGH:
        t &= _HIGH
        if t.ndim == 2:  # OR of the columns (faster than a reduction along a short axis)
            t = functools.reduce(np.bitwise_or, (t[:, j] for j in range(t.shape[1])))
        bad = t != 0
    for mul, shift, mask in _SWAR:
        x *= mul
        x >>= shift
        if mask is not None:
            x &= mask
    return x, bad


def _words(buf: np.ndarray) -> np.ndarray:
    """(B - 7,) uint64: the 8 bytes from each position of ``buf`` as one word (a view)."""
    base = buf[: buf.size - buf.size % 8].view(_U)
    return as_strided(base, shape=(buf.size - 7,), strides=(1,), writeable=False)


def parse_decimals(
    buf: np.ndarray, start: np.ndarray, end: np.ndarray, dot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The float64 of each cell ``buf[start:end]``, or a mark where it needs ``float``.

    Args:
        buf: (B,) uint8, the bytes; every ``end`` is at least :data:`FRACTION_DIGITS`
            (the bytes before a cell may be anything: a header line does).
        start: (n,) int64, where each cell starts (cells are not empty).
        end: (n,) int64, where each ends (the byte after it).
        dot: (n,) int64, the position of the cell's decimal point, ``end`` where it has
            none (a second point is found as a byte that is no digit).

    Returns:
        ``(values, done)``: (n,) float64 and (n,) bool; where ``done`` is False the cell
        is not in the form converted here (it may still be a number) and its value is 0.
    """
    if not LITTLE_ENDIAN:
        return np.zeros(start.size), np.zeros(start.size, dtype=bool)
    neg = buf[start] == 45  # "-"
    n_int = dot - start
    n_int -= neg
    n_frac = end - dot
    n_frac -= 1
    np.maximum(n_frac, 0, out=n_frac)
    n_digits = n_int + n_frac
    ok = n_digits > 0
    ok &= n_frac <= FRACTION_DIGITS
    if (
        n_int.min(initial=0) < 0
        or dot.min(initial=8) < 8
        or end.min(initial=FRACTION_DIGITS) < FRACTION_DIGITS
    ):
        ok &= (n_int >= 0) & (dot >= 8) & (end >= FRACTION_DIGITS)  # the words lie in the buffer
    wide = n_int > 8
    rest = None
    if wide.any():
        rest = np.flatnonzero(wide & ok & (n_int <= INT_DIGITS) & (dot >= INT_DIGITS))
        ok &= ~wide
    np.minimum(n_int, 8, out=n_int)
    np.minimum(n_frac, FRACTION_DIGITS, out=n_frac)
    # The integer digits, right-aligned in a word ending at the point.
    words = _words(buf)
    iw = words[np.maximum(dot - 8, 0)]
    whole, ibad = _digits(iw, _KEEP[np.maximum(n_int, 0)])
    values, done = _finish(buf, whole, n_digits, n_frac, end, neg, ok, ibad)
    if rest is not None and rest.size:
        # Up to 16 digits before the point: two words.
        d = dot[rest]
        iw = sliding_window_view(buf, INT_DIGITS)[d - INT_DIGITS].view(_U)
        k = np.minimum(d - start[rest] - neg[rest], INT_DIGITS)
        i2, ibad = _digits(iw, np.stack((_KEEP[np.clip(k - 8, 0, 8)], _KEEP[np.minimum(k, 8)]), axis=1))
        whole = i2[:, 0] * _U(100_000_000) + i2[:, 1]
        values[rest], done[rest] = _finish(
            buf,
            whole,
            n_digits[rest],
            n_frac[rest],
            end[rest],
            neg[rest],
            np.ones(rest.size, dtype=bool),
            ibad,
        )
    return values, done


def _finish(
    buf: np.ndarray,
    whole: np.ndarray,
    n_digits: np.ndarray,
    n_frac: np.ndarray,
    end: np.ndarray,
    neg: np.ndarray,
    ok: np.ndarray,
    ibad: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The numbers of cells whose integer part is ``whole``, with their fractions read here."""
    # The fraction digits, right-aligned in three words ending at the cell's end.
    words = _words(buf)
    triples = as_strided(words, shape=(words.size - 16, 3), strides=(1, 8), writeable=False)
    fw = triples[np.maximum(end - FRACTION_DIGITS, 0)]
    frac, fbad = _digits(fw, np.take(_KEEP3, n_frac, axis=0))
    if ibad is not None:
        ok &= ~ibad
    if fbad is not None:
        ok &= ~fbad
    # The digits as one integer w below 2**64, or marked: up to 19 digits are; with more
    # (leading zeros, say), an estimate decides (with room for its error).
    long = np.flatnonzero(n_digits > 19)
    if long.size:
        estimate = whole[long] * _POW10_F[n_frac[long]] + frac[long, 0] * 1e16
        ok[long] &= estimate < 1.8e19
    w = whole * _POW10_U[n_frac]
    w += frac[:, 0] * _U(10**16)
    w += frac[:, 1] * _U(100_000_000)
    w += frac[:, 2]
    if use_extended:
        q = w.astype(np.longdouble)
        q /= _POW10_L[n_frac]
        # Exactly halfway between two float64 in 64 bits: left to float.
        low = q.view(np.uint64)[::2] & _U(0x7FF)
        ok &= low != _U(0x400)
        values = q.astype(np.float64)
    else:
        ok &= w < _U(2**53)
        ok &= n_frac <= 22
        values = w.astype(np.float64)
        values /= _POW10_F[n_frac]
    np.negative(values, out=values, where=neg)
    values[~ok] = 0.0
    return values, ok
