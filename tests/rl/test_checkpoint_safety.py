"""Checkpoints are inputs: nothing in one runs, and nothing in one is built or flown before it is checked.

Each crafted file is the shipped Berlin policy with one part altered (or a pickle that runs code); each must be
refused with one line naming the part, quickly and without allocating, and every command that loads a
checkpoint must print that line and exit 2."""

from __future__ import annotations

import dataclasses
import io
import os
import re
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from uamfleet.cli import benchmark, render
from uamfleet.rl.checkpoint import NET_LIMITS, Checkpoint, CheckpointError
from uamfleet.rl.legacy import upgrade_checkpoint
from uamfleet.rl.trainer import load_policy
from uamfleet.zoo import pretrained_path

SHIPPED = pretrained_path("berlin")


def altered(tmp_path: Path, name: str, **changes) -> Path:
    """The shipped Berlin policy with ``changes`` applied (Checkpoint fields), saved as ``name``."""
    ckpt = Checkpoint.load(SHIPPED)
    path = tmp_path / name
    dataclasses.replace(ckpt, **changes).save(path)
    return path


def with_tensor(tmp_path: Path, name: str, key: str, value: torch.Tensor | None) -> Path:
    model = dict(Checkpoint.load(SHIPPED).model)
    if value is None:
        del model[key]
    else:
        model[key] = value
    return altered(tmp_path, name, model=model)


def torch_bytes(obj: object) -> bytes:
    buffer = io.BytesIO()
    torch.save(obj, buffer)
    return buffer.getvalue()


def exploit(marker: Path) -> object:
    class Exploit:  # unpickling it runs a shell command that creates the marker file
        def __reduce__(self):
            return (os.system, (f"touch {marker}",))

    return Exploit()


def test_upgrade_never_runs_the_code_of_a_crafted_file(tmp_path):
    marker, path = tmp_path / "ran", tmp_path / "evil.pt"
    payload = {"numpy_rng": np.random.get_state(), "args": {"scenario": "berlin_p4"}, "model": exploit(marker)}
    path.write_bytes(torch_bytes(payload))
    before = path.read_bytes()
    with pytest.raises(CheckpointError, match=r"evil.pt holds more than tensors and NumPy arrays") as refused:
        upgrade_checkpoint(path)
    assert not marker.exists()
    assert path.read_bytes() == before  # refused files are left as they were
    with pytest.raises(ValueError) as loading:
        Checkpoint.load(path)
    assert not marker.exists()
    for message in (str(refused.value), str(loading.value)):  # no refusal advises an unsafe step
        assert "weights_only=False" not in message and "trust" not in message, message
        assert "\n" not in message


def test_a_foreign_global_is_not_sent_to_upgrade(tmp_path):
    marker, path = tmp_path / "ran", tmp_path / "evil.pt"
    path.write_bytes(torch_bytes({"model": exploit(marker)}))
    with pytest.raises(CheckpointError, match=r"GLOBAL posix.system.*no uamfleet checkpoint holds") as refused:
        load_policy(path)
    assert "upgrade_checkpoint" not in str(refused.value) and not marker.exists()


def test_trust_is_explicit_and_warns_what_it_means(tmp_path):
    marker, path = tmp_path / "ran", tmp_path / "evil.pt"
    path.write_bytes(torch_bytes({"model": exploit(marker)}))
    with pytest.warns(UserWarning, match=r"any code the file holds runs now"), pytest.raises(CheckpointError):
        upgrade_checkpoint(path, trust=True)  # it ran (that is what trust means), then the result was refused
    assert marker.exists()


def test_upgrade_of_a_safe_file_does_not_warn(tmp_path):
    path = tmp_path / "old.pt"
    old = torch.load(SHIPPED, weights_only=True)
    old["numpy_rng"] = np.random.get_state()  # format 1 pickled the NumPy RNG state
    old.pop("format")
    path.write_bytes(torch_bytes(old))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        upgrade_checkpoint(path)
    assert Checkpoint.load(path).numpy_rng["keys"] == [int(k) for k in old["numpy_rng"][1]]


def test_a_huge_network_is_refused_before_anything_is_allocated(tmp_path):
    config = Checkpoint.load(SHIPPED).net_config
    huge = altered(tmp_path, "huge.pt", net_config={**config, "d_model": 2**20})
    assert huge.stat().st_size < 1_000_000
    start = time.perf_counter()
    with pytest.raises(CheckpointError, match=r"huge.pt: net_config d_model=1048576 must be an integer in 1 ... "):
        load_policy(huge)
    assert time.perf_counter() - start < 2.0
    # within the limit, but not what the tensors are: built on the meta device, named, still no allocation
    big = altered(tmp_path, "big.pt", net_config={**config, "d_model": NET_LIMITS["d_model"]})
    start = time.perf_counter()
    with pytest.raises(CheckpointError, match=r"big.pt: tensor '[^']+' has shape \[\d+(, \d+)*\]; its network needs"):
        load_policy(big)
    assert time.perf_counter() - start < 2.0


@pytest.mark.parametrize(
    ("net_config", "message"),
    [
        ({"d_model": 0}, r"d_model=0 must be an integer in 1"),
        ({"d_model": 32.0}, r"d_model=32.0 must be an integer"),
        ({"hidden": True}, r"hidden=True must be an integer"),
        ({"variant": 7}, r"variant=7 must be a str"),
        ({"variant": "huge"}, r"net_config is not a valid network: variant='huge' is unknown"),
        ({"layers": 96}, r"net_config has field\(s\) \['layers'\]"),
    ],
)
def test_bad_network_configs_are_named(tmp_path, net_config, message):
    path = altered(tmp_path, "bad.pt", net_config={**Checkpoint.load(SHIPPED).net_config, **net_config})
    with pytest.raises(CheckpointError, match=message):
        Checkpoint.load(path)


def test_tensors_of_another_shape_are_named_before_load_state_dict(tmp_path):
    model = Checkpoint.load(SHIPPED).model
    key = next(k for k, v in model.items() if v.dim() == 2)
    wrong = with_tensor(tmp_path, "wrong.pt", key, torch.zeros(model[key].shape[0], model[key].shape[1] + 1))
    with pytest.raises(CheckpointError, match=rf"wrong.pt: tensor '{key}' has shape \[\d+, \d+\]; its network"):
        load_policy(wrong)
    missing = with_tensor(tmp_path, "missing.pt", key, None)
    with pytest.raises(CheckpointError, match=rf"missing.pt: lacks tensor '{key}'"):
        load_policy(missing)
    extra = with_tensor(tmp_path, "extra.pt", "spare.weight", torch.zeros(3))
    with pytest.raises(CheckpointError, match=r"extra.pt: holds tensor 'spare.weight'"):
        load_policy(extra)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_non_finite_weights_and_statistics_are_refused(tmp_path, bad):
    model = Checkpoint.load(SHIPPED).model
    key = next(iter(model))
    poisoned = model[key].clone()
    poisoned.view(-1)[0] = bad
    path = with_tensor(tmp_path, "nan.pt", key, poisoned)
    with pytest.raises(CheckpointError, match=rf"nan.pt: model tensor '{key}' holds 1 NaN or infinite value"):
        load_policy(path)
    stats = Checkpoint.load(SHIPPED).obs_normalizer
    assert stats is not None
    field = next(iter(stats))
    var = stats[field]["var"].clone()
    var.view(-1)[0] = bad
    path = altered(tmp_path, "stats.pt", obs_normalizer={**stats, field: {**stats[field], "var": var}})
    with pytest.raises(CheckpointError, match=rf"normaliser '{field}' var holds 1 NaN or infinite"):
        load_policy(path)


def test_the_shipped_policies_still_load():
    for name in ("berlin", "berlin_fleet", "berlin_fleet_v1", "berlin_fleet4"):
        policy, _ = load_policy(pretrained_path(name))
        assert policy.net is not None


@pytest.mark.parametrize(
    ("cli", "argv"),
    [
        (render.cli, ["--checkpoint", "{path}", "--out", "{tmp}/x.html"]),
        (benchmark.cli, ["--checkpoint", "{path}", "--count", "1", "--out-csv", "{tmp}/b.csv", "--out-md",
                         "{tmp}/b.md", "--jobs", "1"]),
    ],
)  # fmt: skip
def test_commands_print_one_line_and_exit_2(tmp_path, capsys, cli, argv):
    config = Checkpoint.load(SHIPPED).net_config
    path = altered(tmp_path, "huge.pt", net_config={**config, "d_model": 2**20})
    code = cli([a.format(path=path, tmp=tmp_path) for a in argv])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.count("\n") == 0 and "d_model=1048576" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["huge.pt"]  # nothing written


def test_normaliser_statistics_must_fit_and_make_sense(tmp_path):
    stats = Checkpoint.load(SHIPPED).obs_normalizer
    assert stats is not None
    field = next(iter(stats))
    negative = {**stats, field: {**stats[field], "var": -stats[field]["var"] - 1.0}}
    with pytest.raises(CheckpointError, match=rf"normaliser '{field}' var is negative"):
        load_policy(altered(tmp_path, "negative.pt", obs_normalizer=negative))
    wider = {**stats, field: {k: torch.cat([v, v]) if k != "count" else v for k, v in stats[field].items()}}
    with pytest.raises(CheckpointError, match=rf"the observation normaliser of '{field}' has shape"):
        load_policy(altered(tmp_path, "wider.pt", obs_normalizer=wider))
    with pytest.raises(CheckpointError, match=r"its obs_normalizer is a list, not a dict"):
        load_policy(altered(tmp_path, "list.pt", obs_normalizer=[1, 2]))
    words = {**stats, field: {**stats[field], "count": "many"}}
    with pytest.raises(CheckpointError, match=rf"normaliser '{field}' count is not numbers"):
        load_policy(altered(tmp_path, "words.pt", obs_normalizer=words))


def test_a_folder_fifo_or_too_long_path_is_named_as_what_it_is(tmp_path):
    os.mkfifo(tmp_path / "fifo.pt")  # opening it would block until a writer comes: it must not be opened
    long = "x" * 5000
    for path, message in (
        (tmp_path, f"checkpoint {tmp_path} is a folder, not a file; give a checkpoint file in it"),
        (tmp_path / "fifo.pt", f"checkpoint {tmp_path / 'fifo.pt'} is not a regular file (a FIFO"),
        (long, "File name too long; shorten the path"),
    ):
        with pytest.raises(OSError) as caught:
            load_policy(path)
        text = str(caught.value)
        assert message in text and "does not exist" not in text and "[Errno" not in text, text
        assert "\n" not in text and len(text) < 500  # a 5,000-character path is shown by its ends
    assert "(5,000 characters)" in text


@pytest.mark.parametrize(
    ("device", "message"),
    [
        ("bogus", "device='bogus' is not a torch device; use 'cpu', 'cuda' or 'cuda:<index>'"),
        ("cuda:7", "device='cuda:7' is not on this machine"),
    ],
)
def test_a_device_is_named_not_blamed_on_the_checkpoint(device, message):
    from uamfleet.zoo import pretrained

    if device.startswith("cuda") and torch.cuda.is_available() and torch.cuda.device_count() > 7:
        pytest.skip("this machine has a cuda:7")
    with pytest.raises(ValueError, match=re.escape(message)) as caught:
        pretrained(device=device)
    assert "loads safely" not in str(caught.value)
    with pytest.raises(ValueError, match=re.escape(message)):
        load_policy(SHIPPED, device=device)


def test_render_with_a_checkpoint_folder_is_one_line(tmp_path, capsys):
    code = render.cli(["--checkpoint", str(tmp_path), "--out", str(tmp_path / "x.html")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "is a folder, not a file" in err and "[Errno" not in err, err
    assert list(tmp_path.iterdir()) == []
