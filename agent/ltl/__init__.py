"""LTL planning core (ltl-planning.md §1–§5): parser, Büchi translation, product, plans.

Pure code: stdlib, numpy and networkx only (architecture.md §4).
"""
