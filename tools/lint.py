#!/usr/bin/env python3
"""Layout lints the compiler does not check: no non-test Rust source over 700 lines, and no
two struct, enum or trait names alike across the workspace's non-test sources (a newcomer
searching for a name finds one thing). Test files are exempt: `tests.rs`, anything under a
`tests/` or `benches/` folder, and the binary's fuzz targets.

And the repository stands alone: no file in it (code, tests, docs) names a path outside it —
a relative path that climbs above the repository from the file's own folder, a path into the
folder beside the repository, or the absolute path of the folder holding it. The one exception
is tools/broad.py, the one lookup of the BROAD data, which may be kept beside the repository.
Exits 1 and lists what breaks."""

import pathlib
import re
import subprocess
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


# The lookup that may look beside the repository (its docstring says where and why).
OUTSIDE_ALLOWED = {"tools/broad.py"}
# Where this project's own machines keep, beside the repository, what it must not need.
BESIDE = "shared"
# A run of parent steps in a written path, and what follows them.
CLIMB = re.compile(r"((?:\.\./)+)[\w.{}/-]*")
# Python's k-th ancestor of a file.
ANCESTOR = re.compile(r"\.parents\[(\d+)\]")
# The folder holding the repository, or a folder in it, reached by a parent step in any spelling:
# a written path, pathlib's parent, os.path.join's "..", and the root's parent by name.
PARENT_STEP = r"(?:\.\.|\bparent)\W{1,12}" + BESIDE + r"\b"
ROOT_PARENT = r"\bROOT(?:\.parent\b|\W{1,6}\.\.\W)"
BESIDE_REFS = re.compile(f"{PARENT_STEP}|{ROOT_PARENT}")


def repository_files() -> list[pathlib.Path]:
    """The repository's files: those git tracks, and new ones it does not ignore (without git,
    every file but build output, the venv and logs)."""
    try:
        out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard",
                              "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        return [ROOT / p for p in sorted(set(out.decode().split("\0"))) if p]
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", "target", ".venv", "logs", "__pycache__"}
        return [p for p in sorted(ROOT.rglob("*"))
                if not skip & set(p.relative_to(ROOT).parts)]


def outside_paths(rel: pathlib.Path, text: str) -> list[str]:
    """What in `text`, the file `rel` of the repository, names a path outside it, by line."""
    depth = len(rel.parts) - 1
    found = []
    for n, line in enumerate(text.splitlines(), 1):
        said = [f"'{m.group(0)}' climbs out of the repository" for m in CLIMB.finditer(line)
                if m.group(1).count("../") > depth]
        said += [f"'{m.group(0)}' climbs out of the repository" for m in ANCESTOR.finditer(line)
                 if int(m.group(1)) > depth and "__file__" in line]
        said += [f"'{m.group(0)}' names the folder beside the repository"
                 for m in BESIDE_REFS.finditer(line)]
        found += [f"{rel}:{n}: {s}" for s in said]
    return found


def stands_alone() -> list[str]:
    """Every place where a file of the repository names a path outside it."""
    problems = []
    for path in repository_files():
        rel = path.relative_to(ROOT)
        if str(rel) in OUTSIDE_ALLOWED or not path.is_file():
            continue
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue  # a picture
        problems += outside_paths(rel, text)
    return problems


def main() -> int:
    problems = stands_alone()
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
