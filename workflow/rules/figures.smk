rule figures:
    """The campaign's figures (paper Fig. 7-12 equivalents)."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
        windows="results/{campaign}/windows.parquet",
        characteristic="results/{campaign}/characteristic.parquet",
    output:
        [
            report(
                f"results/{{campaign}}/figures/{name}.png",
                caption=f"../report/{name}.rst",
                category="{campaign}",
                labels={"campaign": "{campaign}", "figure": name},
            )
            for name in FIGURES
        ],
    log:
        "logs/{campaign}/figures.log",
    script:
        "../scripts/figures.py"
