# shellcheck shell=bash
# shellcheck disable=SC2034  # the variables are for the scripts that source this file
# The test cluster's pinned versions, in one place (sourced by tests/cluster/*.sh).
# Kubernetes and etcd are also pinned in build/go.mod (build.sh refuses a mismatch): etcd is
# the server module Kubernetes itself requires, so the pair is the one upstream tests.

# Kubernetes: kube-apiserver, kube-controller-manager, kube-scheduler, kubectl, kubelet,
# kube-proxy, all from k8s.io/kubernetes through the Go module proxy.
KUBERNETES_VERSION=v1.34.4
# etcd, from go.etcd.io/etcd/server/v3 (the version k8s.io/kubernetes requires).
ETCD_VERSION=v3.6.4
# CoreDNS, the cluster's DNS (github.com/coredns/coredns, built with go install).
COREDNS_VERSION=v1.15.0
# The pod sandbox image: Kubernetes' pause.c (build/pause in the k8s.io/kubernetes module)
# built here, under the name and tag of Kubernetes' own (the kubelet and containerd ask for it).
PAUSE_IMAGE=registry.k8s.io/pause:3.10.1
COREDNS_IMAGE=registry.k8s.io/coredns/coredns:$COREDNS_VERSION
# The S3-compatible object store of the archive tests: Versity's S3 gateway over a folder
# (github.com/versity/versitygw, Apache-2.0; MinIO's server is AGPL).
VERSITYGW_VERSION=v1.8.0
# Kueue, for the two-team walkthrough (tests/e2e/teams.sh local): the manager built from
# sigs.k8s.io/kueue, its manifests from the module's config/default (kustomize).
KUEUE_VERSION=v0.17.0
KUEUE_IMAGE=registry.k8s.io/kueue/kueue:$KUEUE_VERSION
