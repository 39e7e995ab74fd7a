"""uamfleet.rl: the MSHA networks (``networks``), rollout storage and GAE (``buffer``), the PPO loss (``ppo``), the
training options (``options``), checkpoints (``checkpoint``), the run folder and its log (``runs``), the policy at
inference and ``load_policy`` (``policy``) and the training loop (``trainer``: ``train(args) -> result``)."""
