"""The parameter sweep of parameter_sweep.py on dask.distributed: one task per sweep point.

By default a LocalCluster of worker processes runs here (one thread each: every task is a
single-threaded simulation that releases the GIL while it steps). --scheduler ADDRESS
(tcp://host:8786) uses a running cluster instead; its workers need fsm importable (installed
with pip, or PYTHONPATH pointing at a build tree on a shared disk). This script uploads
indentation.py and parameter_sweep.py to the workers, and the task function,
parameter_sweep.measure_point, imports fsm on the worker. Writes sweep.csv and sweep.png to --out.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/dask_sweep.py --out /tmp/dsweep
    ... --workers 4                        # local processes
    ... --scheduler tcp://10.0.0.5:8786    # a real cluster (see docs/python.md)
    ... --quick                            # 2 workers, the small sweep (test suite)
"""
import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import parameter_sweep  # noqa: E402


def worker_versions():
    """What a worker sees: fsm's version and where it was imported from (runs on the worker)."""
    import fsm

    return fsm.__version__, fsm.__file__


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="dask-sweep-out", help="output folder")
    ap.add_argument("--quick", action="store_true", help="the small sweep on 2 workers (tests)")
    ap.add_argument("--scheduler", help="address of a running dask scheduler (tcp://host:8786)")
    ap.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes")
    args = ap.parse_args()

    from dask.distributed import Client, LocalCluster

    start = time.perf_counter()
    cluster = None
    if args.scheduler:
        client = Client(args.scheduler)
    else:
        # Workers are spawned processes; they inherit this environment (PYTHONPATH finds fsm).
        cluster = LocalCluster(n_workers=2 if args.quick else args.workers, threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        # Ship the example modules so remote workers can unpickle the task function.
        for name in ("indentation.py", "parameter_sweep.py"):
            client.upload_file(os.path.join(HERE, name))
        versions = client.run(worker_versions)
        print(f"{len(versions)} workers at {client.scheduler.address}:")
        for worker, (version, where) in sorted(versions.items()):
            print(f"  {worker}: fsm {version} from {where}")
        points = parameter_sweep.sweep_points(args.quick)
        futures = client.map(parameter_sweep.measure_point, points, pure=False)
        results = client.gather(futures)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    wall = time.perf_counter() - start
    parameter_sweep.print_table(results)
    busy = sum(r["wall"] for r in results)
    csv_path, png_path = parameter_sweep.write_outputs(results, args.out)
    print(f"{len(results)} points: {busy:.1f} s of work in {wall:.1f} s wall (cluster start-up "
          f"included); wrote {csv_path} and {png_path}")


if __name__ == "__main__":
    main()
