"""Print ``name==version`` for every dependency of Hearth at the lowest version that
pyproject.toml allows (core dependencies and every optional extra, dev included).

"Lowest" is the oldest release on the package index that satisfies the requirement (the
index is asked with ``pip index versions``, one look-up per dependency). Used by
scripts/lowest-deps.sh; also ``--list`` prints the requirements it read.
"""
from __future__ import annotations

import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

try:
    import tomllib
except ImportError:             # Python 3.10
    from pip._vendor import tomli as tomllib
try:
    from packaging.requirements import Requirement
    from packaging.version import InvalidVersion, Version
except ImportError:             # not installed: pip's own copy
    from pip._vendor.packaging.requirements import Requirement
    from pip._vendor.packaging.version import InvalidVersion, Version

def requirements(pyproject: Path) -> list[Requirement]:
    project = tomllib.loads(pyproject.read_text())["project"]
    out = [Requirement(r) for r in project.get("dependencies", [])]
    for reqs in project.get("optional-dependencies", {}).values():
        out += [Requirement(r) for r in reqs if not r.startswith("hearth")]
    seen, unique = set(), []
    for r in out:
        if r.marker is not None and not r.marker.evaluate():
            continue
        if r.name.lower() not in seen:
            seen.add(r.name.lower())
            unique.append(r)
    return unique


def released_versions(name: str) -> list[Version]:
    out = subprocess.run([sys.executable, "-m", "pip", "index", "versions", "--retries", "1",
                          "--timeout", "30", name],
                         capture_output=True, text=True)
    m = re.search(r"Available versions: (.*)", out.stdout)
    if out.returncode != 0 or not m:
        sys.exit(f"lowest-deps: cannot list the versions of {name} on the package index: "
                 f"{(out.stderr or out.stdout).strip().splitlines()[-1:]}")
    versions = []
    for text in m.group(1).split(","):
        try:
            versions.append(Version(text.strip()))
        except InvalidVersion:
            pass
    return versions


def lowest(req: Requirement) -> Version:
    allowed = sorted(v for v in released_versions(req.name)
                     if not v.is_prerelease and req.specifier.contains(v))
    if not allowed:
        sys.exit(f"lowest-deps: no release of {req.name} satisfies {req}")
    return allowed[0]


def main(argv: list[str]) -> int:
    pyproject = Path(argv[1]) if len(argv) > 1 and not argv[1].startswith("-") else \
        Path(__file__).resolve().parents[1] / "pyproject.toml"
    reqs = requirements(pyproject)
    if "--list" in argv:
        print("\n".join(str(r) for r in reqs))
        return 0
    for r in reqs:
        if not any(s.operator in (">=", "==", "~=", "===") for s in r.specifier):
            sys.exit(f"lowest-deps: {r} has no lower bound: give it one in pyproject.toml")
    with ThreadPoolExecutor(8) as pool:        # one index look-up per dependency, in parallel
        for r, v in zip(reqs, pool.map(lowest, reqs)):
            print(f"{r.name}=={v}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
