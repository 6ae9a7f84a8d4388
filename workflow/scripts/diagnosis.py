"""Rule diagnosis: the campaign's sim-to-real gap diagnosis -> diagnosis.json and the gap figure."""
from pathlib import Path

from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.diagnosis import run_diagnosis

with job(snakemake) as j:
    result = run_diagnosis(Path(snakemake.input.cases).parent, Settings.from_config(snakemake.config))
    j.log.info("verdict %s (explained: %s); %s %s -> %s, shrink %s; %s s", result["verdict"], result.get("explained"),
               result["metric"], result["gap_before"], result["gap_after"], result["shrink"], result.get("seconds"))
