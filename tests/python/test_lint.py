"""tools/lint.py's length checks: a function's lines counted by its braces, not fooled by braces
in strings, characters or comments; a file or function over its limit named."""

import importlib.util
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("lint", ROOT / "tools" / "lint.py")
lint = importlib.util.module_from_spec(spec)
spec.loader.exec_module(lint)


def function(name: str, body_lines: int, filler: str = "    x += 1;") -> str:
    return f"pub(crate) fn {name}(x: &mut u32) {{\n" + f"{filler}\n" * body_lines + "}\n"


def test_functions_are_measured_by_their_braces():
    limit = lint.MAX_FN_LINES
    tricky = '    let s = "}}{"; let c = \'}\'; // }\n    /* { */ let r = r#"}"#;'
    text = (function("short", limit - 2) + function("long", limit - 1)
            + function("tricky", limit - 1, tricky) + "trait T {\n    fn declared(&self);\n}\n")
    found = {name: n for name, _, n in lint.long_functions(text)}
    # `long` and `tricky` are limit + 1 lines with their signature and closing brace.
    assert found == {"long": limit + 1, "tricky": limit + 1 + (limit - 1)}


def test_a_file_or_function_over_its_limit_is_named():
    assert "at most 600" in lint.over_limit("b.rs", 601, 600, "split")[0]
    assert lint.over_limit("b.rs", 600, 600, "split") == []
