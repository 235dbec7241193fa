"""Seed derivation: independent streams per seed and per stream name, reproducible, validated."""

import numpy as np
import pytest

from pverosion.kernels.random_streams import stream_state

_GAMMA = 0x9E3779B97F4A7C15  # SplitMix64's increment


def test_states_are_reproducible_and_distinct():
    states = [int(stream_state(seed, "freeze_thaw")) for seed in range(1000)]
    assert states == [int(stream_state(seed, "freeze_thaw")) for seed in range(1000)]
    assert len(set(states)) == 1000
    # no seed's state is another's advanced by a few SplitMix64 steps (the failure of state = seed * gamma)
    lookup = set(states)
    for s in states[:50]:
        for k in range(1, 100):
            assert (s + k * _GAMMA) % 2**64 not in lookup
    # streams of one seed differ by name
    assert stream_state(3, "freeze_thaw") != stream_state(3, "particle_fluid")
    assert stream_state(np.int64(3), "freeze_thaw") == stream_state(3, "freeze_thaw")


def test_bits_look_independent_across_consecutive_seeds():
    bits = np.array([int(stream_state(seed, "x")) for seed in range(4096)], dtype=np.uint64)
    ones = np.unpackbits(bits.view(np.uint8)).reshape(len(bits), 64).mean(axis=0)
    assert np.all(np.abs(ones - 0.5) < 5 * 0.5 / np.sqrt(len(bits)))


@pytest.mark.parametrize("seed", [-1, 1.5, True, "3"])
def test_bad_seeds_raise(seed):
    with pytest.raises(ValueError, match="seed"):
        stream_state(seed, "freeze_thaw")
