"""Text -> motion R-precision: an embedder trained into the motion evaluator's space ranks the
right captions first; its file reads back; a bad file is one clear error."""
import numpy as np
import pytest
import torch

from engine.evaluation.evaluator import EvaluatorError, MotionEvaluator
from engine.evaluation.text_motion import (fit, load_text_embedder, mm_distance, save_text_embedder,
                                           text_r_precision_top3)
from engine.synth import SCENARIOS, synthesize
from engine.synth.captions import caption

torch.set_num_threads(1)


def test_an_embedder_learns_which_captions_go_with_which_motion(tmp_path):
    torch.manual_seed(0)
    evaluator = MotionEvaluator().eval()
    clips = [synthesize(SCENARIOS[i % 5], 100 + i) for i in range(20)]
    embedder = fit(evaluator, clips, steps=300, batch=20)
    rng = np.random.default_rng(5)
    texts = [caption(c, rng) for c in clips]                     # paraphrases it has not seen paired
    right = text_r_precision_top3(evaluator, embedder, texts, clips)
    wrong = text_r_precision_top3(evaluator, embedder, texts[5:] + texts[:5], clips)   # other scenarios' texts
    assert right > wrong and right > 3 / 20
    assert mm_distance(evaluator, embedder, texts, clips) < mm_distance(evaluator, embedder, texts[5:] + texts[:5], clips)
    save_text_embedder(embedder, {"steps": 300}, tmp_path / "t.pt")
    again = load_text_embedder(tmp_path / "t.pt")
    assert abs(text_r_precision_top3(evaluator, again, texts, clips) - right) < 0.1   # half precision
    (tmp_path / "bad.pt").write_bytes(b"nope")
    with pytest.raises(EvaluatorError, match="no usable text embedder"):
        load_text_embedder(tmp_path / "bad.pt")
