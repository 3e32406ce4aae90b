"""Shapes against measured markers (photogrammetry): files, surfaces, registration, scores."""
