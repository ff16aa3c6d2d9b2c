"""Text -> motion R-precision and MM Dist (the paper's text-motion alignment figures), with a
text embedder trained into the frozen motion evaluator's space.

The embedder is deliberately not the model's own text encoder (engine.models.text): a bag of
words (engine.text ids) through an MLP to a unit vector, trained contrastively (symmetric
InfoNCE) against the motion evaluator's embeddings of training windows captioned by
engine.synth.captions, several paraphrases each. Its own file (resources/text_evaluator.pt), so
that the motion evaluator and every FID stay as they are.

    python -m engine.evaluation.text_motion --synth data/synth --real data/salsa --steps 3000

What the benchmark calls: load_text_embedder(path) -> TextEmbedder;
text_r_precision_top3(evaluator, embedder, texts, generated) and mm_distance(...).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from ..atomic import atomic_write, write_text
from ..clip import MotionClip
from ..dataset import split_files
from ..io.resample import resample_clip
from ..metrics import r_precision
from ..synth.captions import caption
from ..text import VOCAB_SIZE, tokenize
from .evaluator import (DEFAULT_PATH, R_PRECISION_BATCH, R_PRECISION_TOP_K, EvaluatorError, MotionEvaluator,
                        load_evaluator, motion_embeddings)

FILE_FORMAT = "sketch2colab-text-embedder"
TEXT_PATH = DEFAULT_PATH.with_name("text_evaluator.pt")


class TextEmbedder(nn.Module):
    def __init__(self, embed: int = 256, hidden: int = 128):
        super().__init__()
        self.words = nn.Embedding(VOCAB_SIZE, hidden, padding_idx=0)
        self.head = nn.Sequential(nn.Linear(hidden, 2 * hidden), nn.LeakyReLU(0.2), nn.Linear(2 * hidden, embed))

    def forward(self, ids: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """ids (B, L), mask (B, L) -> (B, embed) unit vectors."""
        pooled = (self.words(ids) * mask[..., None]).sum(1) / mask.sum(1, keepdim=True).clamp_min(1.0)
        return F.normalize(self.head(pooled), dim=-1)


def _tokens(texts: Sequence[str]) -> tuple[torch.Tensor, torch.Tensor]:
    tokens = [tokenize(t) for t in texts]
    return (torch.from_numpy(np.stack([t["text_ids"] for t in tokens])),
            torch.from_numpy(np.stack([t["text_mask"] for t in tokens])))


@torch.no_grad()
def text_embeddings(embedder: TextEmbedder, texts: Sequence[str]) -> np.ndarray:
    return embedder(*_tokens(texts)).double().numpy()


def text_r_precision_top3(evaluator: MotionEvaluator, embedder: TextEmbedder, texts: Sequence[str], generated,
                          shuffle_seed: int | None = 0) -> float:
    """Text -> motion R-precision, top 3 in batches of 32; texts[i] is generated[i]'s."""
    text, motion = text_embeddings(embedder, texts), motion_embeddings(evaluator, generated)
    if shuffle_seed is not None:
        order = np.random.default_rng(shuffle_seed).permutation(len(text))
        text, motion = text[order], motion[order]
    return r_precision(text, motion, top_k=R_PRECISION_TOP_K, batch=R_PRECISION_BATCH)


def mm_distance(evaluator: MotionEvaluator, embedder: TextEmbedder, texts: Sequence[str], generated) -> float:
    """Mean distance between each text's embedding and its motion's."""
    text, motion = text_embeddings(embedder, texts), motion_embeddings(evaluator, generated)
    return float(np.mean(np.linalg.norm(text - motion, axis=-1)))


def save_text_embedder(embedder: TextEmbedder, card: dict, path: str | Path) -> None:
    state = {k: v.detach().cpu().half() for k, v in embedder.state_dict().items()}
    with atomic_write(path) as f:
        torch.save({"format": FILE_FORMAT, "card": card, "state": state}, f)


def load_text_embedder(path: str | Path = TEXT_PATH) -> TextEmbedder:
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
        if not isinstance(blob, dict) or blob.get("format") != FILE_FORMAT:
            raise EvaluatorError(f"{path}: not a text embedder file")
        embedder = TextEmbedder()
        embedder.load_state_dict({k: v.float() for k, v in blob["state"].items()})
    except EvaluatorError:
        raise
    except Exception as e:  # missing, unreadable or foreign weights
        raise EvaluatorError(f"{path}: no usable text embedder ({type(e).__name__})") from None
    return embedder.eval().requires_grad_(False)


# ---- training ---------------------------------------------------------------------------------

def windows(files: Sequence[Path], fps: float, length: int = 120, stride: int = 60) -> list[MotionClip]:
    """Every `length`-frame window of the clips (stride apart; shorter clips whole)."""
    out = []
    for path in files:
        clip = resample_clip(MotionClip.load(path), fps)
        for start in range(0, max(clip.num_frames - length, 0) + 1, stride):
            out.append(clip.slice(start, min(start + length, clip.num_frames)))
    return out


def fit(evaluator: MotionEvaluator, clips: list[MotionClip], steps: int, seed: int = 0, batch: int = 64,
        paraphrases: int = 8, temperature: float = 0.07, lr: float = 2e-3) -> TextEmbedder:
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    motion = torch.from_numpy(motion_embeddings(evaluator, clips)).float()                      # (M, D)
    ids, mask = _tokens([caption(c, rng) for c in clips for _ in range(paraphrases)])
    ids, mask = ids.reshape(len(clips), paraphrases, -1), mask.reshape(len(clips), paraphrases, -1)
    embedder = TextEmbedder()
    opt = torch.optim.AdamW(embedder.parameters(), lr=lr, weight_decay=1e-4)
    for step in range(steps):
        pick = torch.from_numpy(rng.choice(len(clips), min(batch, len(clips)), replace=False))
        which = torch.from_numpy(rng.integers(paraphrases, size=len(pick)))
        text = embedder(ids[pick, which], mask[pick, which])
        logits = text @ motion[pick].t() / temperature
        target = torch.arange(len(pick))
        loss = 0.5 * (F.cross_entropy(logits, target) + F.cross_entropy(logits.t(), target))
        opt.zero_grad()
        loss.backward()
        opt.step()
    return embedder.eval().requires_grad_(False)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--synth", required=True)
    p.add_argument("--real")
    p.add_argument("--evaluator", default=str(DEFAULT_PATH))
    p.add_argument("--out", default=str(TEXT_PATH))
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    evaluator = load_evaluator(args.evaluator)
    splits = [split_files(synth_dir=args.synth)] + ([split_files(real_dir=args.real)] if args.real else [])
    train = windows([f for s in splits for f in s.train], evaluator.config.fps)
    val = windows([f for s in splits for f in s.val], evaluator.config.fps)
    started = time.perf_counter()
    embedder = fit(evaluator, train, args.steps, args.seed)
    seconds = time.perf_counter() - started
    rng = np.random.default_rng(args.seed + 1)
    texts = [caption(c, rng) for c in val]
    figures = {"val_windows": len(val), "val_text_r_precision_top3": text_r_precision_top3(evaluator, embedder, texts, val),
               "val_mm_distance": mm_distance(evaluator, embedder, texts, val)}
    card = {"command": "python -m engine.evaluation.text_motion " + " ".join(argv or sys.argv[1:]),
            "train_windows": len(train), "steps": args.steps, "seed": args.seed, "train_s": round(seconds, 1), **figures}
    save_text_embedder(embedder, card, args.out)
    write_text(Path(args.out).with_suffix(".md"), "\n".join(
        ["# Model card: text embedder for text-motion R-precision", "",
         "Trained into the frozen motion evaluator's space (resources/evaluator.pt) on captions of the "
         "training split's windows (engine.synth.captions, 8 paraphrases each); figures on the val split "
         "(true captions of real motion: the ceiling generated motion is measured against).", ""]
        + [f"- {k}: {v:.4g}" if isinstance(v, float) else f"- {k}: {v}" for k, v in card.items()] + [""]))
    print(card)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
