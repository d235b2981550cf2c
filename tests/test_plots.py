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


def test_the_pressure_map_reads_in_the_unit_of_its_scale_not_of_a_few_compressed_pockets():
    import numpy as np

    from hmdem.plots import field_scale

    # a 30 kPa field with three 2 GPa domains: the scale ends at the 99.5th percentile, in kPa
    field = np.r_[np.linspace(0.0, 30e3, 997), [2e9, 2e9, 2e9]]
    unit, factor, low, top, cut = field_scale(field)
    assert (unit, factor, cut) == ("kPa", 1e3, True)
    assert low == 0.0 and top == pytest.approx(np.percentile(field, 99.5) / 1e3)
    # a field whose top half percent is its maximum: its full range, uncut, in its own unit
    unit, factor, low, top, cut = field_scale(np.r_[np.linspace(-1e6, 9.3e8, 500), np.full(10, 9.3e8)])
    assert (unit, cut) == ("MPa", False) and low == -1.0 and top == pytest.approx(930.0)
    # a uniform field has no range to scale over: vmax None
    assert field_scale(np.full(10, 5e3))[3] is None
