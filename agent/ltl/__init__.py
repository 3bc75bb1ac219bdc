"""LTL planning core (ltl-planning.md §1–§5; paper §II-A, Algorithm 1). Pure code: stdlib, numpy
and networkx only (architecture.md §4).

Modules, from formula to plan:

* ``formula``, ``lexer``, ``parser``, ``printer`` — immutable trees and Spot's syntax exactly
  (§1; the grammar table is docs/ltl.md);
* ``lasso`` — exact evaluation on lasso words u·v^ω (§2, the reference semantics);
* ``rewrite`` → ``alternating`` → ``tgba`` (→ ``branching``) → ``degeneralize`` →
  ``simulation`` (→ ``fair_simulation``, ``wdba``) → ``buchi`` — the translator (§2); ``bdd``
  and ``guards`` hold the symbolic Boolean guards (``truth_table`` the bit-parallel ones used
  inside the construction over few atoms), ``hoa`` the HOA v1 export, ``hoa_reader``
  the HOA import, ``task`` the one place that tells a task's formula from its HOA file,
  ``batch`` the ``translate -F`` driver, ``emptiness`` the emptiness check with witness;
* ``transition_system`` (§3), ``product`` (§4), ``search`` and ``planner`` (§5), ``diagnose``
  (why a task is unsatisfiable); ``graphs`` holds the shared SCC/BFS helpers.

Entry points: ``parser.parse``, ``buchi.translate``, ``task.task_automaton``, ``hoa.to_hoa``,
``lasso.holds``, ``planner.plan_robot``, ``planner.plan``, ``planner.replan``,
``planner.buchi_step``.
"""
