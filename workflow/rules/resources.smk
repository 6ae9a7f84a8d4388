# Cluster resources of every rule (Slurm account, partition, runtime, memory) from one table,
# config/resources.yaml: its `default` row, updated by the row named after the rule, if any.
# Unpacked into each rule's resources directive as **rule_resources("<name>"). A local run ignores account
# and partition. Without the table (a project copied with only config/config.yaml) the rules get Snakemake's
# and the cluster's defaults, and a warning says so.

import logging
import os

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

RESOURCES_TABLE = "config/resources.yaml"


def load_resources_table(path):
    """The resources table at `path`, validated against workflow/schemas/resources.schema.yaml;
    None when there is none."""
    if not os.path.isfile(path):
        logging.getLogger("isokinetic").warning(
            "%s not found: jobs get no account, partition, runtime or memory from it (defaults apply)", path
        )
        return None
    with open(path, encoding="utf-8") as f:
        table = yaml.safe_load(f)
    try:
        validate(table, schema="../schemas/resources.schema.yaml")
    except WorkflowError as err:
        raise WorkflowError(f"{path}: not a valid resources table", err) from err
    return table


RESOURCES = load_resources_table(RESOURCES_TABLE)


def rule_resources(rule):
    """The resources of `rule`: the table's default row updated by the rule's own row (if any);
    none without a table."""
    if RESOURCES is None:
        return {}
    return {**RESOURCES["default"], **RESOURCES.get(rule, {})}
