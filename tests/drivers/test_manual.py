"""The manual stage: the operator sets the angle and types what the scale reads (anchors-protocols §0)."""

import pytest

from drivers.errors import DeviceFault, LimitError
from drivers.interfaces import Limits, TwoAxisTable
from drivers.manual import ManualAxis, OperatorCancelled


class Operator:
    """A scripted operator: answers each request with the next reading, and remembers what was asked."""

    def __init__(self, *readings):
        self.readings = list(readings)
        self.asked = []

    def __call__(self, axis_name, target_deg):
        self.asked.append((axis_name, target_deg))
        return self.readings.pop(0)


def test_move_asks_the_operator_and_keeps_the_angle_read_from_the_scale():
    operator = Operator(29.95)
    axis = ManualAxis("zenith", ask=operator)
    axis.move_to(30.0)
    assert operator.asked == [("zenith", 30.0)]
    assert axis.position_deg() == 29.95, "the reading, not the target"
    assert axis.is_moving() is False


def test_position_before_the_first_move_is_the_initial_reading():
    assert ManualAxis("az", ask=Operator(), initial_deg=12.5).position_deg() == 12.5


def test_cancel_is_a_typed_error_and_keeps_the_last_position():
    axis = ManualAxis("zenith", ask=Operator(10.0, None))
    axis.move_to(10.0)
    with pytest.raises(OperatorCancelled, match="cancelled"):
        axis.move_to(20.0)
    assert axis.position_deg() == 10.0


@pytest.mark.parametrize("reading", [float("nan"), float("inf"), "ten"])
def test_a_reading_that_is_not_an_angle_is_a_fault(reading):
    with pytest.raises(DeviceFault):
        ManualAxis("zenith", ask=Operator(reading)).move_to(10.0)


def test_soft_limits_are_checked_before_the_operator_is_asked():
    operator = Operator()
    axis = ManualAxis("zenith", ask=operator, limits=Limits(0.0, 60.0))
    with pytest.raises(LimitError):
        axis.move_to(61.0)
    assert operator.asked == []


def test_home_asks_for_zero():
    operator = Operator(0.02)
    axis = ManualAxis("azimuth", ask=operator, initial_deg=40.0)
    axis.home()
    assert operator.asked == [("azimuth", 0.0)]
    assert axis.position_deg() == 0.02


def test_stop_identify_and_wait():
    axis = ManualAxis("azimuth", ask=Operator(5.0))
    axis.stop()
    assert axis.identify() == "manual stage azimuth"
    axis.move_to(5.0, wait=False)
    assert axis.wait_until_stopped(timeout_s=0.1) == 5.0


def test_two_manual_axes_make_a_table():
    operator = Operator(44.9, 20.1)
    table = TwoAxisTable(ManualAxis("azimuth", ask=operator), ManualAxis("zenith", ask=operator))
    table.move_to(45.0, 20.0)
    assert operator.asked == [("azimuth", 45.0), ("zenith", 20.0)]
    assert table.position() == (44.9, 20.1)
