"""Semantic segmentation of potentially moving objects (ONNX / LiteRT networks).

Segmenter: one image -> label image. fetch/resolve_model: the public models in
a user cache. SemanticMasks: per-frame labels for SLAM, asynchronous with
optical-flow propagation. segment_sequence: a label cache for a sequence.
"""
from dynaorb.segmentation.catalog import CATALOG, DEFAULT_MODEL
from dynaorb.segmentation.fetch import cache_dir, fetch, resolve_model
from dynaorb.segmentation.mask_source import FrameLabels, SemanticMasks, SemanticOptions
from dynaorb.segmentation.model_card import InputSpec, ModelCard
from dynaorb.segmentation.segmenter import Segmentation, Segmenter, load_card

__all__ = ["CATALOG", "DEFAULT_MODEL", "FrameLabels", "InputSpec", "ModelCard", "SemanticMasks",
           "SemanticOptions", "Segmentation", "Segmenter", "cache_dir", "fetch", "load_card", "resolve_model"]
