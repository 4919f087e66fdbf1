"""A real dask.distributed cluster for the tests in this folder: a scheduler and two worker
processes of one thread each (the CI machine has two cores), shared by the whole session.

Workers get their own FMU cache (FEATHERSTAR_CACHE in their environment), so the FMU test sees
them build from nothing.
"""
import pytest

distributed = pytest.importorskip("distributed", reason="the dask extra (pip install '.[test]') is not installed")


@pytest.fixture(scope="session")
def worker_fmu_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("worker-fmu-cache")


@pytest.fixture(scope="session")
def cluster(worker_fmu_cache):
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
        worker_dashboard_address=None, env={"FEATHERSTAR_CACHE": str(worker_fmu_cache)},
    ) as local:
        yield local


@pytest.fixture
def client(cluster):
    """A plain client for the tests' own looks at the cluster (worker pids, placement)."""
    with distributed.Client(cluster.scheduler_address, set_as_default=False) as plain:
        plain.wait_for_workers(2, timeout=60)
        yield plain
