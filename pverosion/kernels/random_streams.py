"""Independent random streams from user seeds.

Every stochastic stage takes a ``seed``; the streams of different seeds must
be statistically independent, so that a sweep over seeds 0, 1, 2, ... gives
independent samples. A generator whose state is the seed itself (or the seed
times a constant) fails this: SplitMix64 advances its state by the constant
``0x9E3779B97F4A7C15``, so a state of ``seed * 0x9E3779B97F4A7C15`` makes
seed ``k``'s stream seed 0's shifted by ``k`` draws.

:func:`stream_state` instead hashes the seed with NumPy's
:class:`~numpy.random.SeedSequence` (the derivation behind
:func:`numpy.random.default_rng`), together with a fixed tag naming the
stream, so two stages given the same seed do not draw the same numbers
either. The result is the same on every machine and NumPy version that keeps
SeedSequence's documented algorithm.
"""

from __future__ import annotations

import zlib

import numpy as np

__all__ = ["stream_state"]


def stream_state(seed: int, stream: str) -> np.uint64:
    """A 64-bit generator state for ``seed``, independent of every other seed's and stream's.

    Parameters
    ----------
    seed : int
        The user's seed, a non-negative integer (any size).
    stream : str
        Name of the random stream (e.g. ``"freeze_thaw"``); streams of one
        seed with different names are independent.

    Returns
    -------
    numpy.uint64
        The starting state of a SplitMix64 generator.

    Raises
    ------
    ValueError
        ``seed`` not a non-negative integer.

    Examples
    --------
    >>> stream_state(0, "freeze_thaw") != stream_state(1, "freeze_thaw")
    True
    >>> stream_state(3, "freeze_thaw") == stream_state(3, "freeze_thaw")
    True
    """
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    tag = zlib.crc32(stream.encode("utf-8"))
    return np.random.SeedSequence(int(seed), spawn_key=(tag,)).generate_state(1, np.uint64)[0]
