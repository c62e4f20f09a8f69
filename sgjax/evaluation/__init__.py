"""Layer 4, evaluation: policies and classical controllers, the batched episode runner,
metrics accumulated in the step, counterfactual metrics, statistics, protocols, reports and
rendering."""
