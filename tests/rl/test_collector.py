"""The collector flies an acting network alone (no optimiser, no learner): what it stores is that network's
sampled actions, their log-probabilities and its values on the stored observations, and the envs' rewards."""

from __future__ import annotations

import numpy as np
import torch
from conftest import small_config
from torch.distributions import Categorical

from uamfleet.config import Request
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.collector import collect_rollout, make_run, normalise
from uamfleet.rl.distributed import Ranks
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, obs_to_torch
from uamfleet.rl.options import TrainArgs

TWO_REQUESTS = small_config(
    requests=(Request(0, (350.0, 150.0), (350.0, 350.0)), Request(0, (150.0, 350.0), (150.0, 150.0))),
    time_limit_steps=6,
)


def test_the_collector_stores_what_the_acting_network_did(tmp_path) -> None:  # type: ignore[no-untyped-def]
    args = TrainArgs.from_flat(dict(num_envs=3, num_steps=8, total_timesteps=3 * 8, num_minibatches=1, run_dir=tmp_path,
                     time_limit_steps=6, progress=False, tensorboard=False, threads=1))  # fmt: skip
    run = make_run(args, TWO_REQUESTS, Ranks(), torch.device("cpu"))
    torch.manual_seed(0)
    net = MSHAActorCritic(run.venv.single_observation_space, NetConfig(variant="le", d_model=16))
    normalizer = ObservationNormalizer(run.obs_shapes)
    obs, _ = run.venv.reset(seed=1)
    run.obs = run.flat(obs)
    first = {k: v.copy() for k, v in run.obs.items()}

    stats = collect_rollout(run, net, normalizer, None)

    buf = run.buffer
    counts = {rms.count for rms in normalizer.fields.values()}
    assert normalizer.fields and all(c > 8 * 3 - 1 for c in counts)  # it took in every step's 3 agents' rows
    np.testing.assert_array_equal(buf.obs["action_mask"][0], first["action_mask"])  # step 0 is the reset's
    rows = np.arange(buf.actions.shape[1])
    assert (buf.obs["action_mask"][np.arange(8)[:, None], rows, buf.actions] > 0.5).all()  # only allowed headings
    with torch.inference_mode():
        for t in range(8):
            logits, value = net(obs_to_torch({k: v[t] for k, v in buf.obs.items()}, "cpu"))
            actions = torch.as_tensor(buf.actions[t])
            np.testing.assert_allclose(buf.logprobs[t], Categorical(logits=logits).log_prob(actions).numpy(), atol=1e-6)
            np.testing.assert_allclose(buf.values[t], value.numpy(), atol=1e-6)
    ends = buf.terminated | buf.truncated
    assert buf.truncated[5].all() and not ends[:5].any()  # every episode hits the 6-step limit, then starts again
    assert np.count_nonzero(buf.final_values[5]) == 3 and not buf.final_values[:5].any()  # bootstrapped there only
    assert stats.episodes.count == 3
    np.testing.assert_allclose(stats.term_sums.sum(), buf.rewards.sum())  # unscaled: the envs' rewards
    again = normalise(run, None, first, update=True)
    assert again is first  # without a normaliser the observation passes as it is
