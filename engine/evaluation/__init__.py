"""The frozen motion evaluator for FID and storyboard-to-motion R-precision (DESIGN.md sec. 4)."""
from .evaluator import (DEFAULT_PATH, EvaluatorConfig, EvaluatorError, MotionEvaluator, embedding_diversity,
                        embedding_fid, fid, load_evaluator, motion_embeddings, r_precision_top3, save_evaluator,
                        story_embeddings)

__all__ = ["DEFAULT_PATH", "EvaluatorConfig", "EvaluatorError", "MotionEvaluator", "embedding_diversity",
           "embedding_fid", "fid", "load_evaluator", "motion_embeddings", "r_precision_top3", "save_evaluator",
           "story_embeddings"]
