"""Hash of each network the loop validates after a tiny seeded round, run under main's code and the branch's
(``--ppo-after`` off): the same two hashes (``ppo_off_identity.log``).

    cd /work/main && python reports/.../ppo_off_identity.py          # main's uamfleet
    cd <worktree> && PYTHONPATH=$PWD python reports/2026-12-04-exit-ppo/ppo_off_identity.py
"""

import hashlib
import tempfile
from pathlib import Path

import uamfleet.rl.expert_iteration as m
from uamfleet.rl.policy import GreedyPolicy


def main():
    hashes = []
    flights = m.validation_flights

    def recording(policy, *a, **k):
        if isinstance(policy, GreedyPolicy):
            h = hashlib.sha256()
            for name, v in policy.net.state_dict().items():
                h.update(name.encode())
                h.update(v.detach().cpu().numpy().tobytes())
            hashes.append(h.hexdigest()[:16])
        return flights(policy, *a, **k)

    m.validation_flights = recording
    opts = dict(
        rounds=1,
        label_instances=2,
        label_futures=2,
        val_instances=2,
        workers=1,
        epochs=1,
        learning_rate=1e-3,
        run_dir=Path(tempfile.mkdtemp()),
        run_name="ident",
    )
    print(m.__file__)
    m.expert_iteration(m.ExItOptions(**opts))
    print("validated networks:", hashes)


if __name__ == "__main__":
    main()
