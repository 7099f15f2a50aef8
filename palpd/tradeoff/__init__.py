"""The speed-for-accuracy study behind `palpd bench tradeoff`: a grid of scan settings (grid), each run on
every scene × seed exactly as `palpd scan` runs it (runs), as independent tasks on Dask or a process pool
(schedulers), summarised as a Pareto front of robot time against accuracy (pareto)."""
