"""Figure helpers: the pressure unit follows the pressures' magnitude."""

import pytest

from hmdem.plots import pressure_unit


@pytest.mark.parametrize("largest, unit", [
    (950.0, "Pa"), (33.5e3, "kPa"), (-33.5e3, "kPa"), (3.54e6, "MPa"), (1.2e9, "GPa"), (0.0, "Pa"),
    (1e3, "kPa"),
])
def test_pressure_unit_reads_the_largest_pressure_as_1_to_999(largest, unit):
    name, factor = pressure_unit(largest)
    assert name == unit
    if largest:
        assert 1.0 <= abs(largest) / factor < 1000.0
