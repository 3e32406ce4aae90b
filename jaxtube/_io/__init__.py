"""Readers and writers of other codes' model files (no solver imports in the readers)."""
