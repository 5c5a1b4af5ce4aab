"""Maps given on the command line (``--joint-names``, ``--akc-plus``): a JSON file or ``key=value`` pairs.

Below every layer that parses them (the operator's joint names, the pipeline config's AKC+ settings); it imports
only :mod:`akc_drake.errors`, so that the renderer's fingerprint (:mod:`akc_drake.evaluation.cache`), which
follows the operator's imports, does not take in the settings of the stages after it.
"""

from __future__ import annotations

from akc_drake.errors import UserError


def read_option_map(text: str, option: str, form: str, example: str, what: str, inline_value=None) -> dict:
    """A map given on the command line: a JSON file (``*.json``) holding an object, its values as the file has
    them, or ``key=value[,key=value...]`` inline, its values as strings (stripped), or typed by ``inline_value``.

    Args:
        text: the option's value; option: its name (``--joint-names``), which each error names.
        form, example: an entry's form (``role=joint``) and an example (``left_shoulder=upper_arm.L``).
        what: what the JSON object maps (``role -> joint name strings``).
        inline_value: ``(key, value string) -> value`` for the inline form (a JSON file's values are typed
            already), raising UserError for a value it cannot read; None keeps the strings.

    Raises:
        UserError: an unreadable file, not JSON, not an object, an entry without "=" or an empty map.
    """
    text = str(text).strip()
    if text.lower().endswith(".json"):
        import json

        try:
            with open(text, encoding="utf-8") as f:
                found = json.load(f)
        except OSError as e:
            raise UserError(f"{option} {text}: cannot read it ({e.strerror or e})") from None
        except json.JSONDecodeError as e:
            raise UserError(f"{option} {text}: not valid JSON ({e})") from None
        if not isinstance(found, dict):
            raise UserError(f"{option} {text}: expected a JSON object of {what}")
        return found
    found = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        key, eq, value = (x.strip() for x in item.partition("="))
        if not eq or not key or not value:
            raise UserError(f"{option}: {item!r} is not {form} (e.g. {example})")
        found[key] = value if inline_value is None else inline_value(key, value)
    if not found:
        raise UserError(f"{option}: empty; give {form}[,{form}...] or a JSON file")
    return found
