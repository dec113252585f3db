"""A family of branches on a Dask cluster: one trace per Gamma, each written to its own file, and the
combined response diagram (the README's "A sweep on Dask").

    pip install '.[dask]'                         # from a checkout: adds dask[distributed]
    python examples/dask_sweep.py                 # on a LocalCluster of 2 worker processes
    python examples/dask_sweep.py tcp://HOST:8786 # on a running scheduler (its workers must see the folder)

It prints one line per Gamma: ``gamma G points N status S first_fold PHI``, then ``diagram PATH``.
"""
import sys

from dask.distributed import Client, LocalCluster

import rodcont


def main(address=None):
    cluster = None if address else LocalCluster(n_workers=2, threads_per_worker=1)
    try:
        with Client(address or cluster) as client:
            result = rodcont.sweep([0.5, 1.0, 2.0], "dask_family", executor=client.get_executor(),
                                   stretch_max=0.5, overwrite=True)
    finally:
        if cluster is not None:
            cluster.close()
    for b in result["branches"]:
        print("gamma", b["gamma"], "points", b["points"], "status", b["status"], "first_fold", b["first_fold"])
    print("diagram", result["diagram"])


if __name__ == "__main__":  # the workers start by importing this file: unguarded, each would start a cluster
    main(*sys.argv[1:])
