"""Bad inputs through Python: the exception class and message each gets (docs/c-api.md
lists the same cases for the C ABI, with the Python exception beside the C status)."""

import numpy as np
import pytest

import lacquer

UP = [0.0, 0.0, 1.0]


def white():
    return lacquer.Material("white_lambert")


def param_case(patterns, value):
    """A material JSON with a registered scalar parameter matching `patterns` set to
    value(min); None when no model has such a parameter yet."""
    for m in lacquer.models():
        for p in m["params"]:
            if p["kind"] == "scalar" and any(s in p["name"] for s in patterns):
                return {"model": m["name"], p["name"]: value(p["min"])}, p["name"]
    return None, None


CASES = [
    # id, callable, exception, message substring
    ("empty-string", lambda: lacquer.Material.from_json(""), lacquer.InvalidJSONError, "EOF while parsing"),
    ("garbage", lambda: lacquer.Material.from_json("lambert please"), lacquer.InvalidJSONError, "invalid JSON"),
    (
        "truncated",
        lambda: lacquer.Material('{"model": "lambert", "albedo": 0.'),
        lacquer.InvalidJSONError,
        "line 1 column",
    ),
    ("trailing", lambda: lacquer.Material('{"model": "lambert"} x'), lacquer.InvalidJSONError, "trailing characters"),
    ("invalid-utf8", lambda: lacquer.Material.from_json(b'{"model": "\xff\xfe"}'), lacquer.InvalidJSONError, "not UTF-8"),
    ("nul-byte", lambda: lacquer.Material.from_json('{"model": "lambert"}\0'), lacquer.InvalidJSONError, "NUL"),
    (
        "nan-parameter",
        lambda: lacquer.Material({"model": "lambert", "albedo": float("nan")}),
        lacquer.InvalidJSONError,
        "expected value",
    ),
    (
        "inf-parameter",
        lambda: lacquer.Material({"model": "lambert", "albedo": float("inf")}),
        lacquer.InvalidJSONError,
        "expected value",
    ),
    ("huge-number", lambda: lacquer.Material('{"model": "lambert", "albedo": 1e999}'), lacquer.InvalidJSONError, "number out of range"),
    ("deep-nesting", lambda: lacquer.Material.from_json("[" * 100_000), lacquer.InvalidJSONError, "recursion limit"),
    ("not-object", lambda: lacquer.Material.from_json("[1, 2, 3]"), lacquer.InvalidMaterialError, "expected a JSON object"),
    ("null", lambda: lacquer.Material.from_json("null"), lacquer.InvalidMaterialError, "expected a JSON object"),
    ("empty-object", lambda: lacquer.Material({}), lacquer.InvalidMaterialError, 'missing "model"'),
    ("model-not-string", lambda: lacquer.Material({"model": 3}), lacquer.InvalidMaterialError, '"model" must be a string'),
    ("unknown-model", lambda: lacquer.Material({"model": "phongg"}), lacquer.UnknownNameError, 'unknown model "phongg"'),
    (
        "unknown-key",
        lambda: lacquer.Material({"model": "lambert", "albdo": 0.5}),
        lacquer.InvalidMaterialError,
        'has no parameter "albdo"',
    ),
    ("wrong-type", lambda: lacquer.Material({"model": "lambert", "albedo": "red"}), lacquer.InvalidMaterialError, '"albedo"'),
    ("two-channels", lambda: lacquer.Material({"model": "lambert", "albedo": [0.1, 0.2]}), lacquer.InvalidMaterialError, '"albedo"'),
    (
        "negative-value",
        lambda: lacquer.Material({"model": "lambert", "albedo": -0.1}),
        lacquer.InvalidMaterialError,
        "outside its range [0, 1]",
    ),
    (
        "above-range",
        lambda: lacquer.Material({"model": "lambert", "albedo": [0.5, 1.5, 0.5]}),
        lacquer.InvalidMaterialError,
        "outside its range [0, 1]",
    ),
    ("unknown-preset", lambda: lacquer.Material("no_such_paint"), lacquer.UnknownNameError, 'unknown preset "no_such_paint"'),
    (
        "preset-extra-keys",
        lambda: lacquer.Material({"preset": "white_lambert", "albedo": 0.5}),
        lacquer.InvalidMaterialError,
        "takes no other keys",
    ),
    ("preset-not-string", lambda: lacquer.Material({"preset": 1}), lacquer.InvalidMaterialError, '"preset" must be a string'),
    ("preset-trailing-space", lambda: lacquer.Material.preset("gold "), lacquer.UnknownNameError, "unknown preset"),
    ("spec-type", lambda: lacquer.Material(3.0), TypeError, "takes a dict"),
    # arrays
    ("wrong-width", lambda: white().eval(np.zeros((4, 2)), np.zeros((4, 2))), lacquer.InvalidArgumentError, "shape (..., 3)"),
    ("no-broadcast", lambda: white().eval(np.zeros((4, 3)), np.zeros((5, 3))), lacquer.InvalidArgumentError, "do not broadcast"),
    ("scalar-direction", lambda: white().eval(1.0, UP), lacquer.InvalidArgumentError, "shape (..., 3)"),
    ("string-array", lambda: white().eval(np.array([["a", "b", "c"]]), [UP]), lacquer.InvalidArgumentError, "numeric"),
    ("nan-direction", lambda: white().eval([[0, 0, 1], [np.nan, 0, 1]], [UP, UP]), lacquer.InvalidDirectionError, "1 of 2 elements"),
    ("inf-direction", lambda: white().pdf(UP, [np.inf, 0, 1]), lacquer.InvalidDirectionError, "wo = [inf, 0, 1]"),
    ("zero-direction", lambda: white().eval([0, 0, 0], UP), lacquer.InvalidDirectionError, "wi = [0, 0, 0]"),
    ("nan-u", lambda: white().sample(UP, [0.5, np.nan, 0.5]), lacquer.InvalidElementError, "u = [0.5, NaN, 0.5]"),
    ("nan-wo-sample", lambda: white().sample([np.nan] * 3, [0.5] * 3), lacquer.InvalidDirectionError, "wo = [NaN, NaN, NaN]"),
    ("duv-without-uv", lambda: white().eval(UP, UP, duv=[0.01] * 4), lacquer.InvalidArgumentError, "without `uv`"),
    ("nan-uv", lambda: white().eval(UP, UP, uv=[np.nan, 0.5]), lacquer.InvalidElementError, "uv = [NaN, 0.5]"),
    ("check-level", lambda: white().check("thorough"), lacquer.InvalidArgumentError, "check level"),
    ("check-level-number", lambda: white().check(7), lacquer.InvalidArgumentError, "unknown check level 7"),
    ("check-unknown-model", lambda: lacquer.check_model("nope"), lacquer.UnknownNameError, 'unknown model "nope"'),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_input(case):
    _, call, exc, text = case
    with pytest.raises(exc) as e:
        call()
    assert text in str(e.value), str(e.value)


@pytest.mark.parametrize(
    "what,patterns,value",
    [("negative roughness", ["rough", "alpha"], lambda lo: -0.1), ("IOR below 1", ["ior", "eta"], lambda lo: 0.5)],
)
def test_registry_parameter_out_of_range(what, patterns, value):
    material, name = param_case(patterns, value)
    if material is None:
        pytest.skip(f"{what}: no registered model has such a parameter yet")
    with pytest.raises(lacquer.InvalidMaterialError) as e:
        lacquer.Material(material)
    assert f'"{name}' in str(e.value)


def test_every_parameter_out_of_range():
    tried = 0
    for m in lacquer.models():
        for p in m["params"]:
            if p["kind"] not in ("scalar", "color", "integer"):
                continue
            step = 1 if p["kind"] == "integer" else 0.1 * max(abs(p["max"] - p["min"]), 1e-3)
            for bad in (p["min"] - step, p["max"] + step):
                value = int(bad) if p["kind"] == "integer" else bad
                with pytest.raises(lacquer.InvalidMaterialError) as e:
                    lacquer.Material({"model": m["name"], p["name"]: value})
                assert f'"{p["name"]}' in str(e.value)
                tried += 1
    assert tried > 0


def test_accepted_oddities():
    m = white()
    # Duplicate keys: the last value wins.
    assert lacquer.Material('{"model": "lambert", "albedo": 0.1, "albedo": 0.2}').to_dict()["albedo"] == [0.2] * 3
    # Non-unit directions are normalised; below-horizon ones give 0.
    assert (m.eval([0, 0, 5], UP) == m.eval(UP, UP)).all()
    assert (m.eval([0, 0, -1], UP) == 0).all()
    # u outside [0, 1) is clamped (u[0] here; clamping u[1], u[2] to an edge of the square
    # maps to the horizon, a failed sample); wo below the horizon is a failed sample too.
    assert m.sample(UP, [7.0, 0.3, 0.6]).pdf > 0
    assert m.sample(UP, [-2.0, 0.3, 0.6]).pdf > 0
    assert m.sample([0, 0, -1], [0.5] * 3).flags == lacquer.LQ_SAMPLE_FAILED
    # Inputs may alias (same array for wi and wo).
    a = np.array([UP] * 3)
    assert m.eval(a, a).shape == (3, 3)
