"""Plant a known bug, run the fast tests that must catch it, restore the file (issue 18).

Usage: python scripts/planted_bugs.py [NAME ...]   (default: all). Needs a clean work tree
for the planted files; each file is restored with ``git checkout`` after its run.
"""
from __future__ import annotations

import subprocess
import sys

METHOD = "algorithms/hierarchical/method.py"
FILTER = "algorithms/hierarchical/safety_filter.py"
PLANTS: dict[str, tuple[str, str, str, str]] = {
    # name: (file, old, new, tests)
    "leak": (METHOD, "own = robot_features(core, state.patch, gs.groups)",
             "own = robot_features(core, state.patch, None)", "tests/algorithms/hierarchical"),
    "truth": (METHOD, "return rollout_step(self.predictor, pred, link_msgs, avail, own_msgs)",
              "rollout_step(self.predictor, pred, link_msgs, avail, own_msgs); return link_msgs.copy()",
              "tests/algorithms/hierarchical"),
    "last": (METHOD, "return rollout_step(self.predictor, pred, link_msgs, avail, own_msgs)",
             "rollout_step(self.predictor, pred, link_msgs, avail, own_msgs); return pred.mem.copy()",
             "tests/algorithms/hierarchical"),
    "own_blocked": (METHOD, "        pos = gs.gather(core.pos).reshape(g, -1)\n",
                    "        pos = gs.gather(core.pos).reshape(g, -1)\n        blocked = blocked | "
                    "self.filter.blocked_cells(pos, gs.gather(core.occupying, fill=False).reshape(g, -1))\n",
                    "tests/algorithms/hierarchical"),
    "executed": (METHOD, "proposed=proposed, critic=critic_features(core),",
                 "proposed=dec.actions, critic=critic_features(core),", "tests/algorithms/hierarchical"),
    "clash_assign": (FILTER, "                clash |= (nw[..., e] == nw[..., f]) | (",
                     "                clash = (nw[..., e] == nw[..., f]) | (",
                     "tests/algorithms/hierarchical/test_safety_filter.py"),
    "swap_or": (FILTER, "(nw[..., e] == p[sel[:, None], rob[None, :, f]]) & (nw[..., f]",
                "(nw[..., e] == p[sel[:, None], rob[None, :, f]]) | (nw[..., f]",
                "tests/algorithms/hierarchical/test_safety_filter.py"),
    "no_rest_pairs": (FILTER, "                rest_pairs = rest_pairs + p0[sel[:, None], rob[None, :, e], rob[None, :, f]]",
                      "                pass", "tests/algorithms/hierarchical/test_safety_filter.py"),
    "no_vs_changed": (FILTER, "        ok &= (c1[gg, r, a] - vs_changed == 0).all(-1)",
                      "        ok &= (c1[gg, r, a] == 0).all(-1)", "tests/algorithms/hierarchical/test_safety_filter.py"),
    "guard_ge": (FILTER, "if k * sel.size > MAX_LEVEL_CANDIDATES:", "if k * sel.size >= MAX_LEVEL_CANDIDATES:",
                 "tests/algorithms/hierarchical/test_safety_filter.py"),
}


def main() -> None:
    for name in sys.argv[1:] or list(PLANTS):
        path, old, new, tests = PLANTS[name]
        text = open(path).read()
        if text.count(old) != 1:
            print(f"{name}: the code to change is not found once in {path} (code moved?)")
            continue
        open(path, "w").write(text.replace(old, new))
        try:
            res = subprocess.run([sys.executable, "-m", "pytest", tests, "-q", "-p", "no:cacheprovider",
                                  "-m", "not slow"], capture_output=True, text=True)
            tail = res.stdout.strip().splitlines()[-1] if res.stdout.strip() else res.stderr[-200:]
            print(f"{name}: {'CAUGHT' if res.returncode else 'NOT CAUGHT'} ({tail})", flush=True)
        finally:
            subprocess.run(["git", "checkout", "-q", path], check=True)


if __name__ == "__main__":
    main()
