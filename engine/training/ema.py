"""Exponential moving average of a module's parameters (buffers are copied, not averaged).

The decay warms up as min(decay, (1 + n) / (10 + n)) over the first updates n: with a fixed
0.999 a 2000-step CPU run would still weigh its random initialisation by 0.999^2000 = 14%.
"""
from __future__ import annotations

import copy

import torch
from torch import nn


class EMA:
    def __init__(self, model: nn.Module, decay: float = 0.999):
        self.decay = decay
        self.updates = 0
        self.shadow = copy.deepcopy(model).eval().requires_grad_(False)

    def current_decay(self) -> float:
        return min(self.decay, (1 + self.updates) / (10 + self.updates))

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        rate = 1.0 - self.current_decay()
        for s, p in zip(self.shadow.parameters(), model.parameters()):
            s.lerp_(p.detach(), rate)
        for s, b in zip(self.shadow.buffers(), model.buffers()):
            s.copy_(b)
        self.updates += 1

    def state_dict(self) -> dict:
        return self.shadow.state_dict()

    def load_state_dict(self, state: dict, updates: int = 0) -> None:
        self.shadow.load_state_dict(state)
        self.updates = updates
