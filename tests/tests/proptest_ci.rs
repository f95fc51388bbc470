//! Property tests run reproducibly: every `proptest!` block in the workspace takes its seed from
//! `PROPTEST_RNG_SEED`, which `.cargo/config.toml` sets (`[env]`, not forced) for every
//! `cargo test`, so CI and a developer's machine generate the same cases, after replaying the
//! committed `proptest-regressions` files. Wider exploration outside CI overrides it
//! (`PROPTEST_RNG_SEED=random` or any number, `PROPTEST_CASES=…`; see docs/testing.md).

use proptest::test_runner::{Config, RngSeed};

#[test]
fn proptest_seed_is_fixed_unless_exploring() {
    let exploring = std::env::var("PROPTEST_RNG_SEED").is_ok_and(|v| v.parse::<u64>().is_err());
    let seed = Config::default().rng_seed;
    if exploring {
        assert_eq!(seed, RngSeed::Random);
    } else {
        assert!(
            matches!(seed, RngSeed::Fixed(_)),
            "proptest would pick a random seed: set PROPTEST_RNG_SEED (.cargo/config.toml [env])"
        );
    }
}
