"""The results registry: each thesis result the project reproduces, its command, its quick
variant and its figures read from the committed result files (``pliant reproduce``)."""

from pliant.reproduce.registry import Figure, FigureError, Quick, Study
from pliant.reproduce.studies import STUDIES, study

__all__ = ["STUDIES", "Figure", "FigureError", "Quick", "Study", "study"]
