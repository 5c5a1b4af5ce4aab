import json

import pytest

from akc_drake.errors import UserError
from akc_drake.option_maps import read_option_map

ARGS = ("--opt", "key=value", "a=1", "key -> value")


def test_inline_pairs_are_stripped_strings():
    assert read_option_map(" a = 1 ,b=x.L,, ", *ARGS) == {"a": "1", "b": "x.L"}


def test_a_json_file_keeps_its_values(tmp_path):
    f = tmp_path / "m.JSON"
    f.write_text(json.dumps({"a": 1.5, "b": True, "c": "x"}))
    assert read_option_map(str(f), *ARGS) == {"a": 1.5, "b": True, "c": "x"}


@pytest.mark.parametrize("text, message", [
    ("a", "^--opt: 'a' is not key=value \\(e.g. a=1\\)$"),
    ("a=", "is not key=value"),
    ("=1", "is not key=value"),
    (" , ", "^--opt: empty; give key=value\\[,key=value...\\] or a JSON file$"),
])
def test_inline_mistakes_are_one_line_naming_the_option(text, message):
    with pytest.raises(UserError, match=message):
        read_option_map(text, *ARGS)


def test_file_mistakes_name_the_file(tmp_path):
    missing = tmp_path / "none.json"
    with pytest.raises(UserError, match=f"^--opt {missing}: cannot read it"):
        read_option_map(str(missing), *ARGS)
    f = tmp_path / "bad.json"
    f.write_text("{nope")
    with pytest.raises(UserError, match="not valid JSON"):
        read_option_map(str(f), *ARGS)
    f.write_text("[1]")
    with pytest.raises(UserError, match="expected a JSON object of key -> value$"):
        read_option_map(str(f), *ARGS)


def test_inline_values_may_be_typed_by_the_caller(tmp_path):
    def number(key, value):
        try:
            return float(value)
        except ValueError:
            raise UserError(f"{key}={value!r} is not a number") from None

    assert read_option_map("a=1.5,b=2", *ARGS, number) == {"a": 1.5, "b": 2.0}
    with pytest.raises(UserError, match="b='x' is not a number"):
        read_option_map("a=1,b=x", *ARGS, number)
    f = tmp_path / "m.json"
    f.write_text('{"a": "1.5"}')  # a file's values are its own: not passed through
    assert read_option_map(str(f), *ARGS, number) == {"a": "1.5"}
