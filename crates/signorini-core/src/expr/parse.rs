//! Tokenizer and recursive-descent parser of the grammar in the module doc.

use super::diff::{add, call, call2, div, mul, neg, pow, sub};
use super::{BUILTINS, Builtin, Expr, ExprError, MAX_DEPTH, Scope};

/// A token and its byte position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Tok<'a> {
    Num(f64),
    Name(&'a str),
    /// One of `+ - * / ^ ( ) ,`.
    Sym(char),
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Token<'a> {
    pub tok: Tok<'a>,
    pub pos: usize,
    pub text: &'a str,
}

/// Splits `src` into tokens.
pub(super) fn tokenize(src: &str) -> Result<Vec<Token<'_>>, ExprError> {
    let bytes = src.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_digit()
            || (c == b'.' && bytes.get(i + 1).is_some_and(u8::is_ascii_digit))
        {
            let start = i;
            while i < bytes.len() && bytes[i].is_ascii_digit() {
                i += 1;
            }
            if i < bytes.len() && bytes[i] == b'.' {
                i += 1;
                while i < bytes.len() && bytes[i].is_ascii_digit() {
                    i += 1;
                }
            }
            if i < bytes.len() && (bytes[i] == b'e' || bytes[i] == b'E') {
                // An exponent needs digits: `1e` and `1e+` are errors, not `1` times `e`.
                let mut j = i + 1;
                if j < bytes.len() && (bytes[j] == b'+' || bytes[j] == b'-') {
                    j += 1;
                }
                let digits = j;
                while j < bytes.len() && bytes[j].is_ascii_digit() {
                    j += 1;
                }
                if j == digits {
                    let end = j.max(i + 1);
                    return Err(ExprError::BadNumber {
                        text: src[start..end].to_string(),
                        pos: start,
                    });
                }
                i = j;
            }
            let text = &src[start..i];
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => out.push(Token {
                    tok: Tok::Num(v),
                    pos: start,
                    text,
                }),
                _ => {
                    return Err(ExprError::BadNumber {
                        text: text.to_string(),
                        pos: start,
                    });
                }
            }
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
                i += 1;
            }
            let text = &src[start..i];
            out.push(Token {
                tok: Tok::Name(text),
                pos: start,
                text,
            });
        } else if b"+-*/^(),".contains(&c) {
            out.push(Token {
                tok: Tok::Sym(c as char),
                pos: i,
                text: &src[i..i + 1],
            });
            i += 1;
        } else {
            // `i` is on a char boundary: every byte consumed so far belongs to ASCII tokens.
            let ch = src[i..].chars().next().unwrap_or('?');
            return Err(ExprError::BadChar { ch, pos: i });
        }
    }
    Ok(out)
}

/// Parses `src` in `scope`.
pub(super) fn parse(src: &str, scope: &Scope) -> Result<Expr, ExprError> {
    let tokens = tokenize(src)?;
    if tokens.is_empty() {
        return Err(ExprError::Empty);
    }
    let mut p = Parser {
        tokens: &tokens,
        at: 0,
        scope,
    };
    let (e, _) = p.expr(0)?;
    match p.peek() {
        None => Ok(e),
        Some(t) => Err(p.unexpected(t)),
    }
}

/// An expression and the depth of its tree.
type Parsed = (Expr, usize);

/// Operands of a flat `+ -` or `* /` chain folded left to right before the chain is split into
/// blocks added pairwise (see `Parser::chain`).
const CHAIN_BLOCK: usize = 32;

/// Depth of the pairwise tree over `blocks` blocks: ⌈log₂ blocks⌉.
fn balanced_depth(blocks: usize) -> usize {
    blocks.next_power_of_two().trailing_zeros() as usize
}

struct Parser<'t, 's> {
    tokens: &'t [Token<'t>],
    at: usize,
    scope: &'s Scope,
}

impl<'t> Parser<'t, '_> {
    fn peek(&self) -> Option<Token<'t>> {
        self.tokens.get(self.at).copied()
    }

    fn peek_sym(&self) -> Option<char> {
        match self.peek()?.tok {
            Tok::Sym(c) => Some(c),
            _ => None,
        }
    }

    fn unexpected(&self, t: Token<'_>) -> ExprError {
        // An operand right after an operand: a missing operator (`2x`, `1 2`, `x (y)`).
        let missing_operator = self.at > 0
            && matches!(t.tok, Tok::Num(_) | Tok::Name(_) | Tok::Sym('('))
            && matches!(
                self.tokens[self.at - 1].tok,
                Tok::Num(_) | Tok::Name(_) | Tok::Sym(')')
            );
        ExprError::Unexpected {
            found: t.text.to_string(),
            pos: t.pos,
            missing_operator,
        }
    }

    fn check_depth(&self, depth: usize) -> Result<usize, ExprError> {
        if depth > MAX_DEPTH {
            let pos = self
                .peek()
                .map_or_else(|| self.tokens.last().map_or(0, |t| t.pos), |t| t.pos);
            Err(ExprError::TooDeep { pos })
        } else {
            Ok(depth)
        }
    }

    /// expr := term (('+' | '-') term)*. `nest` counts the enclosing parentheses and calls.
    fn expr(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        self.chain(nest, ['+', '-'], Self::term)
    }

    /// term := unary (('*' | '/') unary)*
    fn term(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        self.chain(nest, ['*', '/'], Self::unary)
    }

    /// A flat chain `a op b op c …` of one precedence level (`[plus, minus]` = `+ -` or `* /`).
    /// Its first [`CHAIN_BLOCK`] operands fold left to right as written (the usual left-deep
    /// tree, so short chains round exactly as they read); a longer chain folds each block of
    /// [`CHAIN_BLOCK`] operands so, a later block starting from its first operand negated (or
    /// inverted) when it follows `-` (or `/`), and adds (or multiplies) the blocks pairwise. A sum
    /// of n terms is then a tree of depth ≤ CHAIN_BLOCK + ⌈log₂(n/CHAIN_BLOCK)⌉ + the deepest
    /// operand, which is what [`MAX_DEPTH`] limits: many terms side by side are not nesting.
    fn chain(
        &mut self,
        nest: usize,
        [plus, minus]: [char; 2],
        operand: fn(&mut Self, usize) -> Result<Parsed, ExprError>,
    ) -> Result<Parsed, ExprError> {
        let combine = |l: Expr, op: char, r: Expr| match op {
            '+' => add(l, r),
            '-' => sub(l, r),
            '*' => mul(l, r),
            _ => div(l, r),
        };
        let (mut e, mut d) = operand(self, nest)?;
        let mut in_block = 1;
        let mut block_depth = 0;
        let mut blocks = Vec::new();
        while let Some(op) = self.peek_sym().filter(|&c| c == plus || c == minus) {
            self.at += 1;
            let (r, dr) = operand(self, nest)?;
            d = d.max(dr);
            if in_block == CHAIN_BLOCK {
                blocks.push(std::mem::replace(&mut e, Expr::constant(0.0)));
                e = match op {
                    '-' => neg(r),
                    '/' => div(Expr::constant(1.0), r),
                    _ => r,
                };
                in_block = 1;
            } else {
                e = combine(e, op, r);
                in_block += 1;
                block_depth = block_depth.max(in_block - 1);
            }
            self.check_depth(d + block_depth + balanced_depth(blocks.len() + 1))?;
        }
        if blocks.is_empty() {
            return Ok((e, d + block_depth));
        }
        blocks.push(e);
        let depth = d + block_depth + balanced_depth(blocks.len());
        while blocks.len() > 1 {
            let mut next = Vec::with_capacity(blocks.len().div_ceil(2));
            let mut it = blocks.into_iter();
            while let Some(l) = it.next() {
                next.push(match it.next() {
                    Some(r) => combine(l, plus, r),
                    None => l,
                });
            }
            blocks = next;
        }
        let Some(e) = blocks.pop() else {
            unreachable!("at least one block");
        };
        Ok((e, depth))
    }

    /// unary := ('-' | '+') unary | power
    fn unary(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        match self.peek_sym() {
            Some(op @ ('-' | '+')) => {
                self.at += 1;
                self.check_depth(nest + 1)?;
                let (e, d) = self.unary(nest + 1)?;
                let d = self.check_depth(d + 1)?;
                Ok((if op == '-' { neg(e) } else { e }, d))
            }
            _ => self.power(nest),
        }
    }

    /// power := primary ('^' unary)?
    fn power(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        let (base, d) = self.primary(nest)?;
        if self.peek_sym() == Some('^') {
            self.at += 1;
            self.check_depth(nest + 1)?;
            let (exp, de) = self.unary(nest + 1)?;
            let d = self.check_depth(d.max(de) + 1)?;
            return Ok((pow(base, exp), d));
        }
        Ok((base, d))
    }

    /// primary := number | name | name '(' args ')' | '(' expr ')'
    fn primary(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        let Some(t) = self.peek() else {
            return Err(ExprError::UnexpectedEnd {
                expected: "a number, a name or '('",
            });
        };
        match t.tok {
            Tok::Num(v) => {
                self.at += 1;
                Ok((Expr::constant(v), 1))
            }
            Tok::Sym('(') => {
                self.at += 1;
                self.check_depth(nest + 1)?;
                let inner = self.expr(nest + 1)?;
                self.close(t.pos)?;
                Ok(inner)
            }
            Tok::Name(name) => {
                self.at += 1;
                if self.peek_sym() == Some('(') {
                    self.call(name, t.pos, nest)
                } else {
                    self.name(name, t.pos).map(|e| (e, 1))
                }
            }
            Tok::Sym(_) => Err(self.unexpected(t)),
        }
    }

    /// Consumes the `)` that closes the `(` at `open`.
    fn close(&mut self, open: usize) -> Result<(), ExprError> {
        match self.peek() {
            Some(Token {
                tok: Tok::Sym(')'), ..
            }) => {
                self.at += 1;
                Ok(())
            }
            None => Err(ExprError::Unclosed { pos: open }),
            Some(t) => Err(self.unexpected(t)),
        }
    }

    fn name(&self, name: &str, pos: usize) -> Result<Expr, ExprError> {
        if name == "pi" {
            return Ok(Expr::constant(std::f64::consts::PI));
        }
        if let Some(i) = self.scope.variable(name) {
            return Ok(Expr::var(i));
        }
        if let Some(v) = self.scope.parameter(name) {
            return Ok(Expr::constant(v));
        }
        if BUILTINS.iter().any(|(f, _)| *f == name) {
            return Err(ExprError::FunctionWithoutCall {
                name: name.to_string(),
                pos,
            });
        }
        let known = self.scope.names().chain(std::iter::once("pi"));
        Err(ExprError::UnknownName {
            name: name.to_string(),
            pos,
            suggestion: closest(name, known),
        })
    }

    /// A call `name(args)`; the `(` is next.
    fn call(&mut self, name: &str, pos: usize, nest: usize) -> Result<Parsed, ExprError> {
        if name == "pi"
            || self.scope.variable(name).is_some()
            || self.scope.parameter(name).is_some()
        {
            // `x (y)`: a value, then an operand.
            return Err(self.unexpected(self.tokens[self.at]));
        }
        let Some(&(fname, builtin)) = BUILTINS.iter().find(|(f, _)| *f == name) else {
            return Err(ExprError::UnknownFunction {
                name: name.to_string(),
                pos,
                suggestion: closest(name, BUILTINS.iter().map(|(f, _)| *f)),
            });
        };
        let open = self.tokens[self.at].pos;
        self.at += 1;
        self.check_depth(nest + 1)?;
        let mut args = Vec::new();
        let mut depth = 0;
        if self.peek_sym() != Some(')') {
            loop {
                let (a, d) = self.expr(nest + 1)?;
                depth = depth.max(d);
                args.push(a);
                if self.peek_sym() == Some(',') {
                    self.at += 1;
                } else {
                    break;
                }
            }
        }
        self.close(open)?;
        let e = match (builtin, args.as_slice()) {
            (Builtin::One(f), [a]) => call(f, a.clone()),
            (Builtin::Two(f), [a, b]) => call2(f, a.clone(), b.clone()),
            (Builtin::Pow, [a, b]) => pow(a.clone(), b.clone()),
            _ => {
                return Err(ExprError::Arity {
                    name: fname,
                    expected: builtin.arity(),
                    got: args.len(),
                    pos,
                });
            }
        };
        let depth = self.check_depth(depth + 1)?;
        Ok((e, depth))
    }
}

/// The closest of `known` to `name` by edit distance, if close enough to be a likely typo:
/// at most 2 edits, and fewer than the name's length (so `x` does not suggest `y`).
pub(super) fn closest<'a>(name: &str, known: impl Iterator<Item = &'a str>) -> Option<String> {
    let limit = 2.min(name.chars().count().saturating_sub(1));
    known
        .map(|k| (edit_distance(name, k), k))
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k.to_string())
}

/// Levenshtein distance (insertions, deletions, substitutions), with a transposition of two
/// adjacent characters counted as one edit (`hgt`/`htg`).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let w = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * w];
    for (i, row) in d.chunks_mut(w).enumerate() {
        row[0] = i;
    }
    for (j, v) in d.iter_mut().take(w).enumerate() {
        *v = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[(i - 1) * w + j] + 1)
                .min(d[i * w + j - 1] + 1)
                .min(d[(i - 1) * w + j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[(i - 2) * w + j - 2] + 1);
            }
            d[i * w + j] = v;
        }
    }
    d[a.len() * w + b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distances() {
        assert_eq!(edit_distance("hgh", "hgt"), 1);
        assert_eq!(edit_distance("htg", "hgt"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }

    #[test]
    fn suggestions_are_close_names_only() {
        let known = ["hgt", "w", "m", "phi"];
        assert_eq!(closest("hgh", known.into_iter()).as_deref(), Some("hgt"));
        assert_eq!(closest("x", known.into_iter()), None);
        assert_eq!(closest("zzzz", known.into_iter()), None);
        assert_eq!(closest("ph", known.into_iter()).as_deref(), Some("phi"));
    }
}
