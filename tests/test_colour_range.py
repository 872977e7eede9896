"""A colour range typed for the scene's colouring (View > Colour range, issue 45 item 6), checked without a window:
a bad pair is refused in one line saying what is allowed."""

from __future__ import annotations

import pytest
from livox_viz.widgets.colour_range import parse_colour_range, range_words

from livox_viz import LivoxVizError


@pytest.mark.parametrize(("mode", "low", "high", "words"), [
    ("range", "40", "5", "min 40 is not below max 5"),
    ("range", "5", "5", "min 5 is not below max 5"),
    ("height", "nan", "3", "min nan is not a finite number"),
    ("time", "1", "inf", "max inf is not a finite number"),
    ("range", "five", "40", "min 'five' is not a number"),
    ("range", "", "40", "min '' is not a number"),
    ("reflectivity", "0", "100", "allowed: above 0"),
    ("return/tag", "0", "3", "classes, not a scale"),
])
def test_a_bad_colour_range_is_refused_in_one_line_saying_what_is_allowed(mode: str, low: str, high: str,
                                                                          words: str) -> None:
    with pytest.raises(LivoxVizError) as refused:
        parse_colour_range(mode, low, high)
    message = str(refused.value)
    assert words in message and "allowed" in message and "\n" not in message


def test_a_good_colour_range_is_taken_and_said_with_its_unit() -> None:
    assert parse_colour_range("range", " 5 ", "40.5") == (5.0, 40.5)
    assert parse_colour_range("height", "-3", "1e1") == (-3.0, 10.0)
    assert parse_colour_range("reflectivity", "10", "150") == (10.0, 150.0)
    assert range_words("range", (5.0, 40.5)) == "fixed 5 to 40.5 m"
    assert range_words("reflectivity", (10.0, 150.0)) == "fixed 10 to 150"
