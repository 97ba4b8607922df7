# The compiled kernels (Numba cache), before any job that simulates.
#
# The stamp is named by the simulation code's version. It only orders jobs (ancient: rewriting it
# makes no tile out of date); a code edit asks for a stamp of a new name, so the compile job and
# every job after it run again. (One stamp name for every version would hide those jobs' own
# code_version param: Snakemake does not check the jobs after a job it re-runs when their only
# link to it is an ancient input that exists.)


rule compile:
    output:
        stamp=KERNEL_STAMP,
    log:
        "logs/compile.log",
    priority: 10  # the planes wait for it
    conda:
        GEARSIM_ENV
    shell:
        "gearsim compile --stamp {output.stamp} > {log} 2>&1"

