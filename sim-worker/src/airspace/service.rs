//! The airspace authority's HTTP/JSON API (axum), served by the coordinator. See
//! `docs/airspace-api.yaml` (OpenAPI 3.1) for the contract.
