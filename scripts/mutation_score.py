"""Per-module mutation score of the last ``mutmut run`` (``make mutation``), read from ``mutants/``.

killed: a test failed (or timed out) on the mutant; survived: every test passed; no tests: no test in
``[tool.mutmut]``'s selection runs the mutated function. Score = killed / (killed + survived); the
survivors are either killed by a new test or listed as equivalent, with the reason, in docs/mutation.md.
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

#: mutmut's exit codes for a mutant (mutmut/models): 1 and -signal: killed; 0: survived; 33, 34: no tests, skipped
OUTCOME = {0: "survived", 33: "no tests", 34: "skipped", 36: "timeout", 24: "timeout", 5: "no tests"}


def main(root: str = "mutants") -> int:
    metas = sorted(Path(root, "src").rglob("*.py.meta"))
    if not metas:
        print(f"no mutmut results under {root}/: run `make mutation` first", file=sys.stderr)
        return 1
    print(f"{'module':<38} {'mutants':>7} {'killed':>6} {'survived':>8} {'no tests':>8} {'score':>6}")
    for meta in metas:
        codes = json.loads(meta.read_text(encoding="utf-8"))["exit_code_by_key"]
        if not codes:
            continue
        counts = Counter("pending" if c is None else OUTCOME.get(c, "killed") for c in codes.values())
        killed = counts["killed"] + counts["timeout"]
        judged = killed + counts["survived"]
        score = f"{killed / judged:.1%}" if judged else "-"
        name = str(meta.relative_to(Path(root, "src", "econmotor")))[: -len(".py.meta")]
        pending = f"  ({counts['pending']} not run)" if counts["pending"] else ""
        print(f"{name:<38} {len(codes):>7} {killed:>6} {counts['survived']:>8} {counts['no tests']:>8} "
              f"{score:>6}{pending}")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
