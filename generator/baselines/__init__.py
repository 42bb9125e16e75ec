"""The paper's baselines (section 4.2 and 4.3): ``python -m generator.baselines exploration``
(table 2, figure 8) and ``python -m generator.baselines reconstruction`` (table 3, figure 9).
The policies live in ``trajectories``; these modules run them in the Simulator and score
them. Results and how they compare with the paper: docs/results.md."""
