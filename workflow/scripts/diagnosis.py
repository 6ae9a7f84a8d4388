"""Rule diagnosis: the campaign's sim-to-real gap diagnosis -> diagnosis.json and the gap figure."""
from pathlib import Path

from isokinetic.diagnosis import write_diagnosis
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.windows import WindowSpec

log = log_to_file(snakemake.log[0])
spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
result = write_diagnosis(Path(snakemake.input.cases).parent, Path(snakemake.output.json),
                         Path(snakemake.output.figure), spec)
log.info("verdict %s (explained: %s); %s %s -> %s, shrink %s; %s s", result["verdict"], result.get("explained"),
         result["metric"], result["gap_before"], result["gap_after"], result["shrink"], result.get("seconds"))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
