"""Baselines that are not the paper's model: RetrievAdapt (retrieve a training clip by its
storyboard features, retime it, align it, blend it toward the sketch)."""
from .retrieval import (AdaptConfig, Adapted, IndexConfig, Match, RetrievalIndex, adapt, retrieve,
                        retrieve_adapt, sample_retrieval)

__all__ = ["AdaptConfig", "Adapted", "IndexConfig", "Match", "RetrievalIndex", "adapt", "retrieve",
           "retrieve_adapt", "sample_retrieval"]
