"""Campaigns: Monte-Carlo validation of the estimators over a spread of scenarios (docs/campaigns.md)."""
from .report import plots, summarize, table_text, write_run_scenario
from .runner import Store, execute, flatten, run_batch
from .spec import Campaign, load_campaign

__all__ = ["Campaign", "Store", "execute", "flatten", "load_campaign", "plots", "run_batch", "summarize",
           "table_text", "write_run_scenario"]
