"""Analysis of runs: report.json and report.md, figures, the study's Figure 5 and Table 2
comparison, and the traces engine-equality checks compare."""
