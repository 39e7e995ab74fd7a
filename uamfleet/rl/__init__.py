"""uamfleet.rl: the MSHA networks (``networks``), rollout storage and GAE (``buffer``), the PPO loss (``ppo``) and
the training loop (``trainer``: ``train(args) -> result``)."""
