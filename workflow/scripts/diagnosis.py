"""Rule diagnosis: the campaign's sim-to-real gap diagnosis -> diagnosis.json and the gap figure."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.diagnosis import write_diagnosis

with job(snakemake) as j:
    spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
    result = write_diagnosis(Path(snakemake.input.cases).parent, Path(snakemake.output.json),
                             Path(snakemake.output.figure), spec)
    j.log.info("verdict %s (explained: %s); %s %s -> %s, shrink %s; %s s", result["verdict"], result.get("explained"),
               result["metric"], result["gap_before"], result["gap_after"], result["shrink"], result.get("seconds"))
