"""LTL planning core (ltl-planning.md §1–§5): parser, Büchi translation, product, prefix–suffix plans. Pure."""
