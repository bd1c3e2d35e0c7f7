//! Window results shared between parameter vectors that predict a window alike
//! ([`super::Plant::window_key`]). The scan of a sampled time threshold (`session.rs`)
//! ranks its grid values by the same few states-only iterations from the same states;
//! a window whose decisions do not change between two values then goes through the same
//! iterations bit for bit, and is computed once.

use super::normal_equations::WindowLin;
use std::collections::HashMap;
use std::sync::Mutex;

/// The window's key and its state, bit for bit.
type Key = (Vec<u64>, Vec<u64>);

fn key(window_key: &[f64], z: &[f64]) -> Key {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
    (bits(window_key), bits(z))
}

/// One table per window.
type PerWindow<R> = Vec<Mutex<HashMap<Key, R>>>;

/// Per window: linearisations (states only) and costs computed so far.
pub(crate) struct WindowMemo {
    lins: PerWindow<Option<WindowLin>>,
    costs: PerWindow<Option<(f64, usize)>>,
}

fn memoised<R: Clone>(map: &Mutex<HashMap<Key, R>>, k: Key, compute: impl FnOnce() -> R) -> R {
    if let Some(r) = map.lock().expect("not poisoned").get(&k) {
        return r.clone();
    }
    let r = compute();
    map.lock().expect("not poisoned").insert(k, r.clone());
    r
}

impl WindowMemo {
    pub(crate) fn new(windows: usize) -> Self {
        WindowMemo {
            lins: (0..windows).map(|_| Mutex::default()).collect(),
            costs: (0..windows).map(|_| Mutex::default()).collect(),
        }
    }

    /// Window `w`'s states-only linearisation at state `z` under parameters with key
    /// `window_key`.
    pub(crate) fn lin(
        &self,
        w: usize,
        window_key: &[f64],
        z: &[f64],
        compute: impl FnOnce() -> Option<WindowLin>,
    ) -> Option<WindowLin> {
        memoised(&self.lins[w], key(window_key, z), compute)
    }

    /// Window `w`'s weighted cost at state `z` under parameters with key `window_key`.
    pub(crate) fn cost(
        &self,
        w: usize,
        window_key: &[f64],
        z: &[f64],
        compute: impl FnOnce() -> Option<(f64, usize)>,
    ) -> Option<(f64, usize)> {
        memoised(&self.costs[w], key(window_key, z), compute)
    }
}
