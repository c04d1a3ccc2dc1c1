"""Many inputs at once: a batch on this machine's cores or on a Dask cluster.

* :mod:`bgsub.batch.inputs` -- the command line's inputs as one item per video or sequence;
* :mod:`bgsub.batch.plan` -- where each input's outputs go;
* :mod:`bgsub.batch.record` -- completion records: which outputs are complete (resume);
* :mod:`bgsub.batch.job` -- one input as a picklable job, and the function that runs it;
* :mod:`bgsub.batch.threads` -- cores per job (no oversubscription);
* :mod:`bgsub.batch.executors` -- this process, local worker processes, or Dask;
* :mod:`bgsub.batch.runner` -- planning, running with Ctrl-C handled, the report.
"""
