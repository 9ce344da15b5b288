//! The seed corpus of the scenario fuzz target (`fuzz/fuzz_targets/scenario.rs`: a scenario
//! file read, validated and planned), written when `SADESIM_FUZZ_SEEDS` names a folder
//! (`tests/fuzz.sh` sets it): the repository's examples as they are, the quickstart as JSON
//! and as a `kind: List` of two runs. Each is checked to read, and the quickstart to plan.
//! Nothing is committed.

use sadesim_crds::parse_runs;

#[test]
fn the_fuzz_seeds_are_scenarios_that_read() {
    let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let mut seeds: Vec<(String, String)> = Vec::new();
    for dir in [examples.clone(), examples.join("maps")] {
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.expect("a folder entry").path())
            .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
            .collect();
        names.sort();
        for path in names {
            let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let runs = parse_runs(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(runs.iter().all(Result::is_ok), "{}: {runs:?}", path.display());
            seeds.push((path.file_name().expect("a file name").to_string_lossy().into_owned(), text));
        }
    }
    assert!(seeds.len() >= 6, "the examples are missing: {seeds:?}");
    let quickstart = &seeds.iter().find(|(name, _)| name == "quickstart.yaml").expect("examples/quickstart.yaml").1;
    let run = sadesim_crds::parse_run(quickstart).expect("the quickstart reads");
    let plan = crate::plan(&run).expect("the quickstart plans");
    assert!(!plan.drones.is_empty());
    let json = serde_json::to_string_pretty(&run).expect("a run serialises");
    assert_eq!(parse_runs(&json).expect("JSON reads").len(), 1);
    let list = serde_json::json!({"apiVersion": "v1", "kind": "List", "items": [run, run]}).to_string();
    assert_eq!(parse_runs(&list).expect("a List reads").len(), 2);
    seeds.push(("quickstart.json".into(), json));
    seeds.push(("list.json".into(), list));
    let Some(root) = std::env::var_os("SADESIM_FUZZ_SEEDS") else { return };
    let dir = std::path::Path::new(&root).join("scenario");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, text) in &seeds {
        std::fs::write(dir.join(name), text).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
}
