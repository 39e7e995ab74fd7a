"""The command lines, installed as console scripts (pyproject.toml ``[project.scripts]``) that run from any folder.
``uamfleet <command>`` (:mod:`uamfleet.cli.main`; also ``python -m uamfleet``) runs each of them: ``uamfleet train``
is ``uamfleet-train``, ``uamfleet bench`` is ``uamfleet-benchmark``, and so on (``uamfleet --help`` lists them):

    uamfleet-train        train the MSHA policy with PPO          (also: python train/ppo.py, torchrun train/ppo.py)
    uamfleet-rollout      fly a planner / dispatcher, print metrics  (also: python -m eval.rollout)
    uamfleet-render       one episode as a 3-D page (+ PNG figures)  (also: python -m eval.render)
    uamfleet-benchmark    every planner over seeded instances        (also: python -m eval.benchmark)
    uamfleet-paper-table  the paper's Table II beside ours           (also: python -m eval.paper_table)
    uamfleet-msha-table   train and tabulate the MSHA runs           (also: python -m eval.msha_table)
    uamfleet-quickstart   the README's main job                      (also: python -m eval.quickstart)

Each module has ``main(args)`` (for tests and scripts) and ``cli(argv)`` (the command: exit status 2 and one
line on stderr for bad input, see :func:`uamfleet.cli._common.run`). Output paths are relative to the current
folder. The top layer of the package: it may import any other, nothing imports it.
"""
