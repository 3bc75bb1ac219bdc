"""STL core (stl-funnel.md): task language, robustness, funnels, repair. Pure."""
