"""Bag-of-words vocabularies: training on images, the self-built default."""
from dynaorb.vocab.default import build_default, default_vocabulary_path
from dynaorb.vocab.train import collect_images, save, train

__all__ = ["build_default", "collect_images", "default_vocabulary_path", "save", "train"]
