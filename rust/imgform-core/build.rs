//! Sets `cfg(amx)` where the kernels may use Intel's AMX tiles: x86-64
//! Linux, the one OS whose grant of the tiles' state (`arch_prctl`) the
//! crate implements. One name for a predicate that the CPU detection and
//! the network's kernel ask in a dozen places.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(amx)");
    println!("cargo::rerun-if-changed=build.rs");
    let target = |key: &str| std::env::var(key).unwrap_or_default();
    if target("CARGO_CFG_TARGET_ARCH") == "x86_64" && target("CARGO_CFG_TARGET_OS") == "linux" {
        println!("cargo::rustc-cfg=amx");
    }
}
