"""STL core (stl-funnel.md): task language, robustness, funnels, repair. Pure.

Modules (imports point down): ``syntax`` (trees, printer) → ``parser`` → ``analysis`` (concavity,
suprema) → ``evaluate`` (compiled closures with exact gradients, numpy arrays) → ``robustness``
(LSE conjunction) → ``task`` (one sub-task) → ``sequencer`` (φ′ ∧ φ″ …) → ``funnel`` (§4, §5, §7.3)
→ ``messages`` → ``repair`` (stage rules); ``monitor`` (offline/online robustness, trajectory
CSV) beside them. The step function that combines them is the policy
``tlfleet.agent.policy.stl``.
"""
