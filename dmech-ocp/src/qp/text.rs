//! A plain-text form of a [`StageQp`] that other programs read: labelled lines of numbers,
//! matrices row by row, each number in the shortest form that reads back to the same `f64`.
//!
//! ```text
//! stage_qp NX NU NC N
//! x0 …
//! stage 0
//! A … (NX·NX)   B … (NX·NU)   c …   Q …   S … (NX·NU)   R …   q …   r …
//! D … (NC·NX)   E … (NC·NU)   lo …   hi …   soft l1 l2 … (NaN NaN for a hard row)
//! stage 1 … stage N−1
//! terminal
//! Q …   q …   D …   lo …   hi …   soft …
//! end
//! ```
//! each label on its own line followed by its numbers; `inf`, `-inf` and `NaN` as Rust
//! writes them (Python's `float` reads them).

use super::problem::{QpError, Rows, SoftPrice, Stage, StageQp, Terminal};
use nalgebra::SMatrix;
use std::fmt::Write as _;

/// Why a text could not be read as a QP.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum QpTextError {
    /// A label, a number or the header is not what the format has there.
    #[error("QP text, token {at}: expected {expected}, found {found:?}")]
    Syntax {
        /// The token's index.
        at: usize,
        /// What the format has there.
        expected: String,
        /// What the text has.
        found: String,
    },
    /// The header's sizes are not this reader's.
    #[error("QP text of sizes {found:?}, read as {expected:?} (NX, NU, NC)")]
    Sizes {
        /// The reader's sizes.
        expected: (usize, usize, usize),
        /// The text's.
        found: (usize, usize, usize),
    },
    /// The numbers are read but do not make a valid QP.
    #[error(transparent)]
    Invalid(#[from] QpError),
}

impl<const NX: usize, const NU: usize, const NC: usize> StageQp<NX, NU, NC> {
    /// The QP in the text form of the module doc.
    pub fn to_text(&self) -> String {
        let mut s = format!("stage_qp {NX} {NU} {NC} {}\n", self.horizon());
        line(&mut s, "x0", self.x0().iter());
        for (k, st) in self.stages().iter().enumerate() {
            let _ = writeln!(s, "stage {k}");
            matrix(&mut s, "A", &st.a);
            matrix(&mut s, "B", &st.b);
            line(&mut s, "c", st.c.iter());
            matrix(&mut s, "Q", &st.q);
            matrix(&mut s, "S", &st.s);
            matrix(&mut s, "R", &st.r);
            line(&mut s, "q", st.q_vec.iter());
            line(&mut s, "r", st.r_vec.iter());
            rows(&mut s, &st.rows, true);
        }
        let t = self.terminal();
        s.push_str("terminal\n");
        matrix(&mut s, "Q", &t.q);
        line(&mut s, "q", t.q_vec.iter());
        rows(&mut s, &t.rows, false);
        s.push_str("end\n");
        s
    }

    /// Every QP of a text of one or more of them, in order.
    pub fn all_from_text(text: &str) -> Result<Vec<Self>, QpTextError> {
        let mut r = Reader {
            tokens: text.split_whitespace().enumerate().peekable(),
        };
        let mut out = Vec::new();
        while r.tokens.peek().is_some() {
            out.push(r.qp()?);
        }
        Ok(out)
    }
}

fn line<'a>(s: &mut String, label: &str, values: impl Iterator<Item = &'a f64>) {
    s.push_str(label);
    for v in values {
        let _ = write!(s, " {v}");
    }
    s.push('\n');
}

fn matrix<const R: usize, const C: usize>(s: &mut String, label: &str, m: &SMatrix<f64, R, C>) {
    line(s, label, m.transpose().iter());
}

fn rows<const NX: usize, const NU: usize, const NC: usize>(
    s: &mut String,
    rows: &Rows<NX, NU, NC>,
    with_e: bool,
) {
    matrix(s, "D", &rows.d);
    if with_e {
        matrix(s, "E", &rows.e);
    }
    line(s, "lo", rows.lo.iter());
    line(s, "hi", rows.hi.iter());
    let prices: Vec<f64> = rows
        .soft
        .iter()
        .flat_map(|p| p.map_or([f64::NAN; 2], |p| [p.l1, p.l2]))
        .collect();
    line(s, "soft", prices.iter());
}

struct Reader<'a> {
    tokens: std::iter::Peekable<std::iter::Enumerate<std::str::SplitWhitespace<'a>>>,
}

impl Reader<'_> {
    fn next(&mut self, expected: &str) -> Result<(usize, String), QpTextError> {
        self.tokens
            .next()
            .map(|(i, t)| (i, t.to_string()))
            .ok_or_else(|| QpTextError::Syntax {
                at: usize::MAX,
                expected: expected.to_string(),
                found: "the end".to_string(),
            })
    }

    fn label(&mut self, label: &str) -> Result<(), QpTextError> {
        let (at, t) = self.next(label)?;
        match t == label {
            true => Ok(()),
            false => Err(QpTextError::Syntax {
                at,
                expected: label.to_string(),
                found: t,
            }),
        }
    }

    fn number<T: std::str::FromStr>(&mut self) -> Result<T, QpTextError> {
        let (at, t) = self.next("a number")?;
        t.parse().map_err(|_| QpTextError::Syntax {
            at,
            expected: "a number".to_string(),
            found: t,
        })
    }

    fn matrix<const R: usize, const C: usize>(
        &mut self,
        label: &str,
    ) -> Result<SMatrix<f64, R, C>, QpTextError> {
        self.label(label)?;
        let mut m = SMatrix::<f64, R, C>::zeros();
        for r in 0..R {
            for c in 0..C {
                m[(r, c)] = self.number()?;
            }
        }
        Ok(m)
    }

    fn rows<const NX: usize, const NU: usize, const NC: usize>(
        &mut self,
        with_e: bool,
    ) -> Result<Rows<NX, NU, NC>, QpTextError> {
        let mut rows = Rows::free();
        rows.d = self.matrix("D")?;
        if with_e {
            rows.e = self.matrix("E")?;
        }
        rows.lo = self.matrix::<1, NC>("lo")?.transpose();
        rows.hi = self.matrix::<1, NC>("hi")?.transpose();
        let prices: SMatrix<f64, NC, 2> = self.matrix("soft")?;
        for i in 0..NC {
            let (l1, l2) = (prices[(i, 0)], prices[(i, 1)]);
            if !(l1.is_nan() && l2.is_nan()) {
                rows.soft[i] = Some(SoftPrice { l1, l2 });
            }
        }
        Ok(rows)
    }

    fn qp<const NX: usize, const NU: usize, const NC: usize>(
        &mut self,
    ) -> Result<StageQp<NX, NU, NC>, QpTextError> {
        self.label("stage_qp")?;
        let found = (self.number()?, self.number()?, self.number()?);
        if found != (NX, NU, NC) {
            return Err(QpTextError::Sizes {
                expected: (NX, NU, NC),
                found,
            });
        }
        let n: usize = self.number()?;
        let x0 = self.matrix::<1, NX>("x0")?.transpose();
        let mut stages = Vec::with_capacity(n);
        for k in 0..n {
            self.label("stage")?;
            let (at, t) = self.next("the stage's index")?;
            if t != k.to_string() {
                return Err(QpTextError::Syntax {
                    at,
                    expected: k.to_string(),
                    found: t,
                });
            }
            let mut st = Stage::zeros();
            st.a = self.matrix("A")?;
            st.b = self.matrix("B")?;
            st.c = self.matrix::<1, NX>("c")?.transpose();
            st.q = self.matrix("Q")?;
            st.s = self.matrix("S")?;
            st.r = self.matrix("R")?;
            st.q_vec = self.matrix::<1, NX>("q")?.transpose();
            st.r_vec = self.matrix::<1, NU>("r")?.transpose();
            st.rows = self.rows(true)?;
            stages.push(st);
        }
        self.label("terminal")?;
        let mut terminal = Terminal::zeros();
        terminal.q = self.matrix("Q")?;
        terminal.q_vec = self.matrix::<1, NX>("q")?.transpose();
        terminal.rows = self.rows(false)?;
        self.label("end")?;
        Ok(StageQp::new(x0, stages, terminal)?)
    }
}
