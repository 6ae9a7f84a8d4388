# The workflow is workflow/Snakefile (the Snakemake catalog's layout); this file runs it from the root.
include: "workflow/Snakefile"


# An included file cannot set the default target (Snakemake keeps the includer's): name it here.
workflow.default_target = "all"
