"""The chart on a real API server: install, upgrade (an object the new values drop is
deleted, the Deployment rolls), uninstall (nothing of the release is left but the CRD, which
Helm keeps)."""
import subprocess

from conftest import REPO

RELEASE = "sadesim-helm-test"
# Every kind the chart's templates make, namespaced and cluster-scoped.
KINDS = "deployments,services,serviceaccounts,secrets,configmaps,roles,rolebindings,clusterroles,clusterrolebindings"


def helm_run(helm, kubectl, *args):
    result = subprocess.run([helm, f"--kubeconfig={kubectl.kubeconfig}", *args], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, f"helm {' '.join(args)}: {result.stderr}"
    return result.stdout


def release_objects(kubectl) -> dict:
    """{kind/namespace/name: uid} of every object labelled as the release's."""
    items = kubectl.json(KINDS, "-A", "-l", f"app.kubernetes.io/instance={RELEASE}")["items"]
    return {f"{o['kind']}/{o['metadata'].get('namespace', '')}/{o['metadata']['name']}": o["metadata"]["uid"]
            for o in items}


def test_helm_install_upgrade_uninstall_leave_no_orphans(kubectl, helm, namespace):
    chart = str(REPO / "charts/sadesim")
    runs_ns = f"{namespace}-runs"
    kubectl.run("create", "namespace", runs_ns)
    try:
        common = ["-n", namespace, "--set", "image.tag=test", "--set", "workerImage.tag=test"]
        helm_run(helm, kubectl, "install", RELEASE, chart, *common,
                 "--set", "objectStore.create=true", "--set", "objectStore.secretName=store",
                 "--set", f"objectStore.namespaces={{{namespace},{runs_ns}}}",
                 "--set", "objectStore.env.AWS_REGION=us-east-1")
        installed = release_objects(kubectl)
        kinds = {k.split("/")[0] for k in installed}
        assert {"Deployment", "ServiceAccount", "ClusterRole", "ClusterRoleBinding", "Secret"} <= kinds, installed
        assert f"Secret/{runs_ns}/store" in installed
        assert kubectl.exists("crd", "simulationruns.sadesim.io")
        deployment = kubectl.json("deployment", "-n", namespace, "-l", f"app.kubernetes.io/instance={RELEASE}")["items"][0]

        # The upgrade drops the object-store Secrets and changes the operator's flags.
        helm_run(helm, kubectl, "upgrade", RELEASE, chart, *common, "--set", "maxConcurrentRuns=3")
        upgraded = release_objects(kubectl)
        assert not any(k.startswith("Secret/") for k in upgraded), upgraded
        for key, uid in upgraded.items():
            assert installed.get(key) == uid, f"{key} was re-created by the upgrade"
        rolled = kubectl.json("deployment", deployment["metadata"]["name"], "-n", namespace)
        assert rolled["metadata"]["generation"] > deployment["metadata"]["generation"]
        env = {e["name"]: e.get("value") for e in rolled["spec"]["template"]["spec"]["containers"][0]["env"]}
        assert env.get("SADESIM_MAX_CONCURRENT_RUNS") == "3", env

        helm_run(helm, kubectl, "uninstall", RELEASE, "-n", namespace, "--wait")
        assert release_objects(kubectl) == {}
        # Helm keeps CRDs (and so every user's runs) on uninstall.
        assert kubectl.exists("crd", "simulationruns.sadesim.io")
        releases = kubectl.json("secrets", "-n", namespace, "-l", "owner=helm")["items"]
        assert releases == [], [s["metadata"]["name"] for s in releases]
    finally:
        kubectl.run("delete", "namespace", runs_ns, "--wait=true", "--timeout=120s", check=False)
