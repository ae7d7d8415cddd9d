"""The shared policies (radiosity.policies.limits): one seed range, one exposure rule,
one reading of free memory, used by every command."""

import math

import pytest

from radiosity.files.errors import InputError
from radiosity.policies.limits import SEED_LIMIT, available_memory, check_exposure, check_seed


@pytest.mark.parametrize("seed", [0, 1, 2**63 - 1])
def test_seeds_in_range_pass(seed):
    assert check_seed(seed) == seed


@pytest.mark.parametrize("seed", [-1, SEED_LIMIT, 2**70, 1.5, True, "3"])
def test_seeds_out_of_range_name_the_flag(seed):
    with pytest.raises(InputError, match="--seed must be a whole number from 0 to 2\\^63 - 1"):
        check_seed(seed)


@pytest.mark.parametrize("value", [1e-8, 1.0, 1e8])
def test_positive_exposures_pass(value):
    assert check_exposure(value) == value


@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, -math.inf, math.nan])
def test_zero_negative_infinite_and_nan_exposures_are_refused(value):
    with pytest.raises(InputError, match="--exposure must be a positive finite number"):
        check_exposure(value)


def test_available_memory_is_known_and_plausible_here():
    free = available_memory()
    assert free is not None and 1e6 < free < 1e15


def test_the_solver_and_the_display_share_one_memory_reading():
    import display.gl
    import radiosity.transport.solve

    assert display.gl.available_memory is available_memory
    assert radiosity.transport.solve.available_memory is available_memory
