"""Import every module of Hearth's packages (not ``__main__``); print how many, or each
failure as ``module: error`` and exit 1. Used by scripts/lowest-deps.sh."""
from __future__ import annotations

import importlib
import pkgutil
import sys
import traceback

PACKAGES = ("hearth",)


def main() -> int:
    names, failed = [], []
    for top in PACKAGES:
        package = importlib.import_module(top)
        names.append(top)
        for info in pkgutil.walk_packages(package.__path__, prefix=f"{top}."):
            if info.name.rsplit(".", 1)[-1] == "__main__":
                continue
            names.append(info.name)
            try:
                importlib.import_module(info.name)
            except Exception as err:   # report them all, then fail
                failed.append((info.name, err))
                traceback.print_exc(limit=-2)
    for name, err in failed:
        print(f"import-all: {name}: {type(err).__name__}: {err}", file=sys.stderr)
    if failed:
        return 1
    print(f"import-all: {len(names)} modules imported")
    return 0


if __name__ == "__main__":
    sys.exit(main())
