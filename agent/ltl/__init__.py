"""LTL planning core (ltl-planning.md §1–§5; paper §II-A, Algorithm 1). Pure code: stdlib, numpy
and networkx only (architecture.md §4).

Modules, from formula to plan:

* ``formula``, ``parser``, ``printer`` — immutable trees and Spot syntax (§1);
* ``lasso`` — exact evaluation on lasso words u·v^ω (§2, the reference semantics);
* ``rewrite`` → ``alternating`` → ``tgba`` → ``degeneralize`` → ``buchi`` — the translator
  (§2); ``guards`` holds the Boolean guards, ``hoa`` the HOA v1 export, ``emptiness`` the
  emptiness check with witness;
* ``transition_system`` (§3), ``product`` (§4), ``search`` and ``planner`` (§5), ``diagnose``
  (why a task is unsatisfiable); ``graphs`` holds the shared SCC/BFS helpers.

Entry points: ``parser.parse``, ``buchi.translate``, ``hoa.to_hoa``, ``lasso.holds``,
``planner.plan_robot``, ``planner.plan``, ``planner.replan``, ``planner.buchi_step``.
"""
