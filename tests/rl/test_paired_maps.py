"""The two map CNNs computed as one grouped channels-last convolution (uamfleet.rl.encoders.paired_map_features)
give what the two encoders give one by one, forward and backward."""

from __future__ import annotations

import pytest
import torch

from uamfleet.rl.encoders import MapEncoder, paired_map_features


def _pair(seed: int) -> tuple[MapEncoder, MapEncoder]:
    torch.manual_seed(seed)
    return MapEncoder(4), MapEncoder(4)


@pytest.mark.parametrize("batch", [1, 2, 7, 64])
def test_paired_maps_equal_the_two_encoders_one_by_one(batch):
    first, second = _pair(0)
    sinr, visit = torch.randn(batch, 10, 10) * 5.0, torch.rand(batch, 10, 10)
    expected = torch.cat([first(sinr), second(visit)], dim=-1)  # [B, 100, 8]: the SINR map's 4 channels first
    got = paired_map_features(first, second, sinr, visit)
    assert got.shape == (batch, 100, 8)
    torch.testing.assert_close(got, expected, rtol=1e-6, atol=1e-6)


def test_paired_maps_give_each_encoder_its_own_gradient():
    first, second = _pair(1)
    sinr, visit = torch.randn(16, 10, 10), torch.randn(16, 10, 10)
    weights = torch.randn(16, 100, 8)  # a loss that weighs every output differently
    (torch.cat([first(sinr), second(visit)], dim=-1) * weights).sum().backward()
    params = [*first.parameters(), *second.parameters()]
    expected = [p.grad.clone() for p in params if p.grad is not None]
    assert len(expected) == len(params)
    first.zero_grad(), second.zero_grad()
    (paired_map_features(first, second, sinr, visit) * weights).sum().backward()
    for want, p in zip(expected, params, strict=True):
        assert p.grad is not None
        torch.testing.assert_close(p.grad, want, rtol=1e-5, atol=1e-5)


def test_each_patch_goes_through_its_own_encoder():
    first, second = _pair(2)
    a, b = torch.randn(3, 10, 10), torch.randn(3, 10, 10)
    ab, ba = paired_map_features(first, second, a, b), paired_map_features(first, second, b, a)
    assert not torch.allclose(ab[..., :4], ba[..., :4])
    torch.testing.assert_close(ab[..., :4], first(a), rtol=1e-6, atol=1e-6)
    torch.testing.assert_close(ba[..., 4:], second(a), rtol=1e-6, atol=1e-6)
