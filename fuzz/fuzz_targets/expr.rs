//! The expression language: a text parsed over the variables `x` (a coordinate), `y` (its
//! velocity) and `t`, with the parameters `k = 2` and `c = k^2 + 1`; its derivative in `x` and
//! its time derivative; each compiled to a tape and evaluated (`tests/fuzz_corpus.rs` replays
//! the corpus through the same calls).
#![no_main]

use libfuzzer_sys::fuzz_target;
use signorini_core::expr::{Expr, Param, Scope};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let names = ["x".to_string(), "y".to_string(), "t".to_string()];
    let parameters = [
        ("k".to_string(), Param::Value(2.0)),
        ("c".to_string(), Param::Expr("k^2 + 1".into())),
    ];
    let scope = Scope::new(&names, &parameters).expect("the scope");
    if let Ok(e) = Expr::parse(text, &scope) {
        let point = [0.75, -1.25, 2.5];
        for d in [Some(e.derivative(0)), e.time_derivative(1), Some(e)]
            .into_iter()
            .flatten()
        {
            let _ = (d.eval(&point), d.compile().eval(&point));
        }
    }
});
