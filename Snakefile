# isokinetic: steady hydraulic damper characteristics from piecewise constant velocity tests.
# This file only sets up and includes; the stages live in workflow/rules/<stage>.smk.

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/virtual_rig.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/validate.smk"
include: "workflow/rules/windows.smk"
include: "workflow/rules/repeatability.smk"
include: "workflow/rules/characteristic.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/design.smk"
include: "workflow/rules/nominal.smk"
include: "workflow/rules/harmonic.smk"
include: "workflow/rules/models.smk"
include: "workflow/rules/diagnosis.smk"
include: "workflow/rules/blind.smk"
include: "workflow/rules/raw_check.smk"
include: "workflow/rules/provenance.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        all_outputs(),


onsuccess:
    if check_raw_after_run():
        raise WorkflowError("raw data changed during the run: see the errors above")


onerror:
    check_raw_after_run()
