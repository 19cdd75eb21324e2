"""Hand-written values checked against a field's type: one definition for config.json and sweeps."""

import pytest

from pac_host.errors import InputError
from pac_host.typed_values import coerce, describe


@pytest.mark.parametrize("value, hint, expected", [
    (3, float, 3.0), (2.5, float, 2.5), (7, int, 7), (False, bool, False), ("a", str, "a"),
    ({"k": 1}, dict, {"k": 1}), (None, int | None, None), (4, int | None, 4),
    ("a, b,", tuple[str, ...], ["a", "b"]), ([1, 2.5, 3], tuple[float, float, float],
                                              [1.0, 2.5, 3.0]),
    ((1, 2), tuple[int, ...], [1, 2]),
])
def test_a_value_that_fits_comes_back_in_its_type(value, hint, expected):
    got = coerce(value, hint, "x")
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize("value, hint, words", [
    (True, int, "an integer"), (1, bool, "true or false"), (True, float, "a number"),
    (40.5, int, "an integer"), ("1", float, "a number"), (3, str, "a string"),
    ([], dict, "an object"), (None, int, "an integer"), (None, str, "a string"),
    ("a", int | None, "an integer or null"), ([1, 2], tuple[float, float, float],
                                               "a list of 3 (a number, a number, a number)"),
    (["a", 1], tuple[str, ...], "a list of strings"), ("1,2", tuple[int, ...],
                                                       "a list of integers"),
])
def test_a_value_that_does_not_fit_is_named_with_what_it_must_be(value, hint, words):
    with pytest.raises(InputError) as e:
        coerce(value, hint, "setting 'k'")
    assert str(e.value) == f"setting 'k' must be {words}, got {value!r}"
    assert describe(hint) == words


def test_a_type_it_has_no_check_for_is_a_programming_error_not_a_pass():
    with pytest.raises(TypeError):
        coerce(1, list[int], "k")
