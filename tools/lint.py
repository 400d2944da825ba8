#!/usr/bin/env python3
"""Layout lints the compiler does not check: no non-test Rust source over 700 lines, and no
two struct, enum or trait names alike across the workspace's non-test sources (a newcomer
searching for a name finds one thing). Test files are exempt: `tests.rs`, anything under a
`tests/` or `benches/` folder, and the binary's fuzz targets. Exits 1 and lists what breaks."""

import pathlib
import re
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
# Every workspace member (a member inside another, as daemon/core, is walked with it).
MEMBERS = tomllib.loads((ROOT / "Cargo.toml").read_text())["workspace"]["members"]
CRATES = [m for m in MEMBERS if not any(m.startswith(o + "/") for o in MEMBERS)]
MAX_LINES = 700
TYPE = re.compile(r"^\s*(?:pub(?:\([a-z]+\))?\s+)?(?:struct|enum|trait)\s+([A-Z][A-Za-z0-9]*)", re.M)


def is_test(path: pathlib.Path) -> bool:
    parts = path.relative_to(ROOT).parts
    return path.name in ("tests.rs", "fuzz.rs") or "tests" in parts or "benches" in parts


def non_test_part(text: str) -> str:
    """The file without an inline `#[cfg(test)] mod tests { … }` at its end."""
    cut = text.find("#[cfg(test)]\nmod tests {")
    return text if cut < 0 else text[:cut]


def main() -> int:
    problems = []
    defined: dict[str, list[str]] = {}
    for crate in CRATES:
        for path in sorted((ROOT / crate).rglob("*.rs")):
            if "target" in path.relative_to(ROOT).parts or is_test(path):
                continue
            text = non_test_part(path.read_text())
            rel = str(path.relative_to(ROOT))
            lines = text.count("\n")
            if lines > MAX_LINES:
                problems.append(f"{rel}: {lines} lines (at most {MAX_LINES}): split it by job")
            for name in TYPE.findall(text):
                defined.setdefault(name, []).append(rel)
    for name, files in sorted(defined.items()):
        if len(files) > 1:
            problems.append(f"type {name} defined {len(files)} times: {', '.join(files)}")
    for p in problems:
        print(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
