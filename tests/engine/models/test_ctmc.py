"""CTMC phase planner: rate matrices, simplex occupancy, losses, metrics, and learning a phase
schedule from informative features."""
import torch

from engine.models.ctmc import (PhasePlan, PhasePlanner, PhasePlannerConfig, contact_timing_error, ctmc_loss,
                                generator_matrix, integrate_occupancy, kolmogorov_residual, phase_accuracy)

torch.set_num_threads(1)
N, T_LAT = 120, 30


def synthetic_episode(g: torch.Generator):
    """Phase labels approach -> contact -> carry -> contact -> approach with random boundaries,
    and a decoded-looking motion that shows them: a hand closes on the object's anchor, the
    storyboard asks for contact while holding, the object moves only while carried."""
    cuts = torch.sort(torch.randperm(N - 20, generator=g)[:4] + 10).values
    while (cuts.diff() < 6).any():
        cuts = torch.sort(torch.randperm(N - 20, generator=g)[:4] + 10).values
    state = torch.zeros(N, dtype=torch.long)
    for i, c in enumerate(cuts.tolist()):
        state[c:] = [1, 2, 1, 0][i]
    labels = torch.nn.functional.one_hot(state, 3).float()
    holding = state > 0
    carrying = state == 2
    obj = torch.cumsum(carrying.float() * 0.03, 0)[:, None] * torch.tensor([1.0, 0.0, 0.0])  # (N, 3)
    anchors = obj[:, None, None, None] + torch.zeros(N, 1, 2, 3)
    joints = torch.zeros(N, 2, 22, 3)
    gap = torch.where(holding, torch.zeros(N), 0.3 + 0.02 * torch.rand(N, generator=g))
    joints[:, 0, 20] = obj + gap[:, None] * torch.tensor([0.0, 0.0, 1.0])
    joints[:, 1] = obj[:, None] + 2.0                                       # the other person: far
    contact = torch.zeros(N, 2, 2)
    contact[:, 0, 0] = holding.float()
    motion = {"joints": joints, "obj_pose": torch.cat([obj, torch.tensor([1.0, 0, 0, 0]).expand(N, 4)], -1)[:, None],
              "obj_anchors": anchors[:, 0][:, None]}
    return labels, motion, contact


def batch_of(size: int, g: torch.Generator):
    eps = [synthetic_episode(g) for _ in range(size)]
    labels = torch.stack([e[0] for e in eps])
    motion = {k: torch.stack([e[1][k] for e in eps]) for k in eps[0][1]}
    contact = torch.stack([e[2] for e in eps])
    return labels, motion, contact


def test_generator_matrix_rows_sum_to_zero_and_offdiagonals_nonnegative():
    planner = PhasePlanner()
    z = torch.randn(2, T_LAT, 3, 32)
    plan = planner(z, num_frames=N)
    q = plan.rates
    assert q.shape == (2, N, 3, 3)
    assert q.sum(-1).abs().max() < 1e-6
    off = q[..., ~torch.eye(3, dtype=torch.bool)]
    assert (off >= 0).all()
    assert torch.allclose(generator_matrix(torch.ones(6)).sum(-1), torch.zeros(3))


def test_occupancy_stays_on_simplex_and_matches_sequential_integration():
    g = torch.Generator().manual_seed(0)
    rates = generator_matrix(3.0 * torch.rand(2, N, 6, generator=g))      # fast rates stress the scan
    pi0 = torch.softmax(torch.randn(2, 3, generator=g), -1)
    pi = integrate_occupancy(pi0, rates)
    assert pi.shape == (2, N, 3)
    assert (pi >= 0).all() and torch.allclose(pi.sum(-1), torch.ones(2, N), atol=1e-6)
    step = torch.linalg.matrix_exp(rates)
    seq = [pi0]
    for n in range(N - 1):
        seq.append(torch.einsum("bs,bst->bt", seq[-1], step[:, n]))
    assert torch.allclose(pi, torch.stack(seq, 1), atol=1e-5)
    # Integrated exactly, the occupancy nearly satisfies dpi/dn = pi Q (error from the finite difference).
    slow = generator_matrix(0.05 * torch.rand(2, N, 6, generator=g))
    assert kolmogorov_residual(integrate_occupancy(pi0, slow), slow).max() < 1e-4


def test_features_from_latent_motion_and_contacts():
    labels, motion, contact = batch_of(2, torch.Generator().manual_seed(1))
    planner = PhasePlanner()
    h = planner.features(torch.randn(2, T_LAT, 3, 32), motion, contact)
    assert h.shape == (2, N, planner.in_dim)
    h_bare = planner.features(torch.randn(2, T_LAT, 3, 32), None, None, N)
    assert h_bare.shape == h.shape


def test_losses_and_metrics():
    labels, motion, contact = batch_of(3, torch.Generator().manual_seed(2))
    planner = PhasePlanner()
    plan = planner(torch.randn(3, T_LAT, 3, 32), motion, contact)
    loss, parts = ctmc_loss(plan, labels, torch.tensor([1.0, 1.0, 0.0]))
    assert loss.isfinite() and set(parts) == {"kolmogorov", "phase_ce", "rate_entropy_var", "dwell"}
    loss.backward()
    assert planner.rate_head[-1].weight.grad.abs().sum() > 0
    # Perfect prediction: accuracy 1, timing error 0; shifted by 3 frames: error 3.
    assert phase_accuracy(labels, labels) == 1.0
    assert contact_timing_error(labels, labels) == 0.0
    shifted = torch.roll(labels, 3, dims=1)
    assert abs(contact_timing_error(shifted, labels) - 3.0) < 1e-6
    assert phase_accuracy(labels, labels, torch.tensor([0.0, 0.0, 0.0])) != phase_accuracy(labels, labels)  # nan
    # Dwell penalty punishes fast switching.
    fast = PhasePlan(plan.occupancy, generator_matrix(torch.full((3, N, 6), 5.0)))
    slow = PhasePlan(plan.occupancy, generator_matrix(torch.full((3, N, 6), 0.01)))
    assert ctmc_loss(fast)[1]["dwell"] > ctmc_loss(slow)[1]["dwell"] == 0


def test_planner_learns_step_schedule_from_informative_features():
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(3)
    planner = PhasePlanner(PhasePlannerConfig())
    opt = torch.optim.Adam(planner.parameters(), lr=3e-3)
    for _ in range(200):
        labels, motion, contact = batch_of(8, g)
        z = torch.randn(8, T_LAT, 3, 32, generator=g)   # uninformative latent: features must carry it
        loss, _ = ctmc_loss(planner(z, motion, contact), labels)
        opt.zero_grad()
        loss.backward()
        opt.step()
    labels, motion, contact = batch_of(16, torch.Generator().manual_seed(99))
    with torch.no_grad():
        plan = planner(torch.randn(16, T_LAT, 3, 32), motion, contact)
    assert phase_accuracy(plan.occupancy, labels) > 0.9
    assert contact_timing_error(plan.occupancy, labels) < 3.0
