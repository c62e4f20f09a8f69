"""Layer 4, evaluation: policies and classical controllers, the batched episode runner,
metrics accumulated in the step, counterfactual metrics, statistics, protocols, reports and
rendering."""

# The counterfactual metrics register themselves beside the built-in ones: importing any part
# of the evaluation layer gives the whole metric catalogue.
from sgjax.evaluation import counterfactual  # noqa: F401
