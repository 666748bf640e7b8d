"""Plant a known bug, run the fast tests that must catch it, restore the file (issues 11, 18).

Usage: python scripts/planted_bugs.py [NAME ...]   (default: all). Needs a clean work tree
for the planted files; each file is restored with ``git checkout`` after its run.
"""
from __future__ import annotations

import subprocess
import sys

METHOD = "algorithms/hierarchical/method.py"
FILTER = "algorithms/hierarchical/safety_filter.py"
IC3 = "algorithms/ic3net.py"
DEC = "algorithms/decentralized.py"
HIER_TRAIN = "algorithms/hierarchical/training.py"
BASELINE_TESTS = ("tests/algorithms/test_ic3net.py tests/algorithms/test_decentralized.py "
                  "tests/algorithms/common/test_trainer.py")
PLANTS: dict[str, tuple[str, str, str, str]] = {
    # name: (file, old, new, tests)
    # the trainer bugs that once passed the whole suite
    "ic3_no_baseline": (IC3, "adv = crit.adv[..., None].expand_as(active)",
                        "adv = crit.returns[..., None].expand_as(active)", BASELINE_TESTS),
    "ic3_values_not_denormalized": (IC3, "(self.policy.value_norm.denormalize(values)\n", "(values\n",
                                    BASELINE_TESTS),
    "ic3_finished_not_masked": (IC3, "action_loss = -(adv[sl] * logp * m).sum()",
                                "action_loss = -(adv[sl] * logp).sum()", BASELINE_TESTS),
    "ic3_no_gate_term": (IC3, "logp = logp + logp_g.gather(", "logp = logp + 0 * logp_g.gather(", BASELINE_TESTS),
    "dec_critic_frozen": (DEC, "critic_update(self.critic, self.critic_opt,",
                          "critic_update(self.critic, torch.optim.SGD(self.critic.parameters(), lr=0.0),",
                          BASELINE_TESTS),
    # the hierarchical method and its filter
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
    "no_rest_pairs": (FILTER, "                rest_pairs = rest_pairs + p0[sel[:, None], rob[None, :, e], rob[None, "
                              ":, f]]",
                      "                pass", "tests/algorithms/hierarchical/test_safety_filter.py"),
    "no_vs_changed": (FILTER, "        ok &= (c1[gg, r, a] - vs_changed == 0).all(-1)",
                      "        ok &= (c1[gg, r, a] == 0).all(-1)",
                          "tests/algorithms/hierarchical/test_safety_filter.py"),
    # the speed changes (deviation 2 over pairs i < j, the shared critic step)
    "level2_clean_j": (FILTER, "clean_j = clean[:, ju, iu]", "clean_j = clean[:, iu, ju]",
                       "tests/algorithms/hierarchical/test_safety_filter.py"),
    "level2_swap": (FILTER, "(ni == ps[:, ju, None, None]) & (nj == ps[:, iu, None, None])",
                    "(ni == ps[:, iu, None, None]) & (nj == ps[:, ju, None, None])",
                    "tests/algorithms/hierarchical/test_safety_filter.py"),
    "hier_critic_frozen": (HIER_TRAIN, "crit = critic_step(method.critic, method.opt_critic,",
                           "crit = critic_step(method.critic, torch.optim.SGD(method.critic.parameters(), lr=0.0),",
                           "tests/algorithms/hierarchical tests/algorithms/common/test_trainer.py"),
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
            res = subprocess.run([sys.executable, "-m", "pytest", *tests.split(), "-q", "-p", "no:cacheprovider",
                                  "-m", "not slow"], capture_output=True, text=True)
            tail = res.stdout.strip().splitlines()[-1] if res.stdout.strip() else res.stderr[-200:]
            print(f"{name}: {'CAUGHT' if res.returncode else 'NOT CAUGHT'} ({tail})", flush=True)
        finally:
            subprocess.run(["git", "checkout", "-q", path], check=True)


if __name__ == "__main__":
    main()
