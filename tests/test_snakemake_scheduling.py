"""The installed Snakemake keeps the threads of running jobs within --cores (the workflow relies on it: one
2-thread embedded solve at a time on a 2-core machine, NumCalc steps whose memory adds up). Snakemake 9.10 to 9.16
started a lone ready job without counting its threads, so the cores it later freed let jobs overlap."""
import subprocess
import sys
import textwrap

SNAKEFILE = textwrap.dedent('''
    rule all:
        input: "heavy_1.txt", "heavy_2.txt"

    rule seed_1:
        output: "seed_1.txt"
        threads: 1
        shell: "python -c 'import time; print(time.time())' > {output}; sleep 1; python -c 'import time; print(time.time())' >> {output}"

    rule seed_2:
        input: "seed_1.txt"
        output: "seed_2.txt"
        threads: 1
        shell: "python -c 'import time; print(time.time())' > {output}; sleep 1; python -c 'import time; print(time.time())' >> {output}"

    rule heavy:
        input: "seed_{i}.txt"
        output: "heavy_{i}.txt"
        threads: 2
        shell: "python -c 'import time; print(time.time())' > {output}; sleep 2; python -c 'import time; print(time.time())' >> {output}"
''')


def test_running_jobs_never_use_more_threads_than_cores(tmp_path):
    """A chain of single-thread jobs, each the only one ready, then 2-thread jobs on --cores 2: at no time do the
    running jobs' threads add up to more than 2."""
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    snakemake = [sys.executable, "-m", "snakemake", "--cores", "2", "--quiet"]
    subprocess.run(snakemake, cwd=tmp_path, check=True, capture_output=True, text=True)
    intervals = []
    for name, threads in (("seed_1", 1), ("seed_2", 1), ("heavy_1", 2), ("heavy_2", 2)):
        start, end = (float(x) for x in (tmp_path / f"{name}.txt").read_text().split())
        intervals.append((start, end, threads, name))
    for start, _, _, name in intervals:
        running = [(n, t) for s, e, t, n in intervals if s <= start < e]
        assert sum(t for _, t in running) <= 2, f"at the start of {name}: {running} on --cores 2"
