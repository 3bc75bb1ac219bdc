"""What a finished run leaves: summary, report, figures and the rerun recording.

* ``outputs`` — the files written after the fleet stopped (summary, report, ``run.rrd``);
* ``summary`` — the plain-text summary, a pure function of the run directory;
* ``run_report`` — ``report.md``/``report.json``; ``render`` its text; ``figures`` its plots;
* ``ltl_words`` — the word an LTL robot's trajectory produced and whether it is accepted;
* ``task_verdicts`` — per STL sub-task verdicts; ``paper_values``/``paper_comparison``/
  ``joint_optimum`` — the paper's reported values and the best achievable ones;
* ``fault_table`` — the faults of the run as the report lists them;
* ``viewer`` — the fleet in rerun, replayed or live (the only rerun importer).
"""
