"""The preview student's distillation (engine/models/preview.py): reference paths follow the
guided field, and the loss is the jump velocities' error, zero for a field that is the reference's."""
import torch

from engine.models.conditioning import Conditioning
from engine.models.bundle import ModelConfig
from engine.models.preview import PREVIEW_STEPS, preview_loss, preview_times, reference_path


def decay(z, t, cond, pos, occupancy):
    """dz/dt = z: integrated from t = 1 down to 0, z(t) = z(1) e^(t - 1)."""
    return z


def test_the_reference_path_follows_the_field():
    z1 = torch.randn(2, 5, 3, 4)
    states, positions = reference_path(decay, lambda z: z[..., :3], z1, None, None, substeps=8)
    assert len(states) == PREVIEW_STEPS + 1 and len(positions) == PREVIEW_STEPS and positions[0] is None
    for state, t in zip(states, preview_times()):
        assert torch.allclose(state, z1 * torch.exp(torch.tensor(t - 1.0)), rtol=1e-3)


def test_the_reference_path_takes_as_many_heun_steps_whatever_the_jumps():
    calls = []

    def counted(z, t, cond, pos, occupancy):
        calls.append(float(t[0]))
        return z

    for steps in (1, 2, 4):
        calls.clear()
        states, _ = reference_path(counted, lambda z: z[..., :3], torch.randn(1, 5, 3, 4), None, None, steps)
        assert len(states) == steps + 1 and len(calls) == 16      # REFERENCE_STEPS Heun steps, two calls each


def test_a_bundle_says_how_many_jumps_its_preview_takes():
    assert ModelConfig.from_dict(ModelConfig.default().to_dict()).preview_steps == PREVIEW_STEPS
    written_before = {k: v for k, v in ModelConfig.default().to_dict().items() if k != "preview_steps"}
    assert ModelConfig.from_dict(written_before).preview_steps == 4    # the jumps every earlier preview took


class Jumps(torch.nn.Module):
    """A stand-in preview student whose velocity is a learnable scale of the exact jump's."""

    def __init__(self):
        super().__init__()
        self.scale = torch.nn.Parameter(torch.tensor(1.0))

    def velocity(self, z, t, cond, pos, occupancy):
        jump = 1.0 / PREVIEW_STEPS
        return self.scale * z * (1 - torch.exp(torch.tensor(-jump))) / jump   # exact for z' = z


def _conditioning():
    """A zero-sized conditioning for preview_loss to repeat."""
    return Conditioning(residual=torch.zeros(2, 1, 1, 1), temporal_bias=torch.zeros(2, 1, 1), embed=torch.zeros(2, 1))


def test_the_loss_is_zero_for_the_exact_jumps_and_teaches_otherwise():
    z1 = torch.randn(2, 5, 3, 4)
    states = [z1 * torch.exp(torch.tensor(t - 1.0)) for t in preview_times()]
    positions = [None] + [s[..., :3] for s in states[1:-1]]
    model = Jumps()
    exact = preview_loss(model, states, positions, _conditioning(), None)
    assert exact["loss"] < 1e-10 and {f"jump{k}" for k in range(PREVIEW_STEPS)} <= set(exact)
    with torch.no_grad():
        model.scale.fill_(1.5)
    off = preview_loss(model, states, positions, _conditioning(), None)
    off["loss"].backward()
    assert off["loss"] > 1e-3 and model.scale.grad > 0
