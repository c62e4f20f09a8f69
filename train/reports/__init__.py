"""Reports of runs: learning curves, a grid sweep's table, docs/results.md's generated blocks,
and reproduce's results in marl-eval's layout."""
