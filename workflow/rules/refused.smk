# A campaign the workflow refuses before any job (isokinetic.audit.refused, common.smk REFUSED): its raw
# folder leads outside the raw data folder, or outputs it would have to replace are write-protected.
# It gets none of its jobs; this one fails with the reason, so the run ends failed, every other campaign
# is built (keep-going) and the index lists the campaign with that reason.


rule refused:
    """Fail a refused campaign alone, naming the reason (its output is never written)."""
    output:
        refused_marker(),
    log:
        "logs/_refused/{campaign}.log",
    wildcard_constraints:
        campaign=one_of(REFUSED),
    params:
        code=code_version("refused.py"),
        reason=lambda wildcards: REFUSED[wildcards.campaign],
    script:
        "../scripts/refused.py"
