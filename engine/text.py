"""A storyboard's text as the networks read it: lower-case words mapped to fixed token ids.

The vocabulary is fixed here (the text encoder's embedding table has one row per entry, so it
cannot change without retraining): the words the caption writer uses (engine.synth.captions)
and words an animator is likely to type. Any other word is hashed into one of HASH_BUCKETS
shared ids, so that text never fails to encode; training replaces a share of caption words with
such ids, so that the model learns to read past words it does not know. Id 0 is padding; an
empty text is all padding, which the networks read exactly as "no text" (a dropped text).
"""
from __future__ import annotations

import re
import zlib

import numpy as np

TEXT_TOKENS = 32                # words read; the rest is cut
PAD = 0
HASH_BUCKETS = 64
VOCABULARY = tuple(sorted(set("""
a after alone and approach approaches away back backwards barrel both box bring brings briskly by
canister carefully carries carry carrying carton couple crate dance dances desk down drum each
early end ends fast finishes first floor friends gives go halfway hand hands haul hauls higher
holding it its later lets lift lifts lower meet meets move moves near on one other over pair pass
people person pick place put quickly raise right salsa second set shake shakes slowly soon table
takes the then to together two unhurriedly until up walk walking walks way while
left high low heavy light slow quick run runs running jump step steps turn turns around toward
towards from with without into onto off hold holds grab grabs drop drops give take carried lifted
object thing chair man woman they he she them him her his their first second third start middle
beginning finish stop stops wait waits pause gently hard tired happy angry calm big small long short
""".split())))
_IDS = {word: i + 1 + HASH_BUCKETS for i, word in enumerate(VOCABULARY)}
VOCAB_SIZE = 1 + HASH_BUCKETS + len(VOCABULARY)


def words(text: str) -> list[str]:
    return re.findall(r"[a-z]+", text.lower())


def word_id(word: str) -> int:
    """The word's id: its own, or its hash bucket's (stable across runs and machines)."""
    return _IDS.get(word, 1 + zlib.crc32(word.encode()) % HASH_BUCKETS)


def tokenize(text: str) -> dict[str, np.ndarray]:
    """{"text_ids": (TEXT_TOKENS,) int64, "text_mask": (TEXT_TOKENS,) float32}: up to
    TEXT_TOKENS word ids, then padding (mask 0)."""
    ids = [word_id(w) for w in words(text)[:TEXT_TOKENS]]
    out = np.full(TEXT_TOKENS, PAD, np.int64)
    out[:len(ids)] = ids
    mask = np.zeros(TEXT_TOKENS, np.float32)
    mask[:len(ids)] = 1.0
    return {"text_ids": out, "text_mask": mask}


def with_unknown_words(tokens: dict[str, np.ndarray], share: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """A share of the words replaced by random hash-bucket ids (words the model will not know)."""
    ids = tokens["text_ids"].copy()
    words_at = np.flatnonzero(tokens["text_mask"] > 0)
    swap = words_at[rng.random(len(words_at)) < share]
    ids[swap] = 1 + rng.integers(HASH_BUCKETS, size=len(swap))
    return {"text_ids": ids, "text_mask": tokens["text_mask"]}
