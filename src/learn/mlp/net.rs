//! A network's shape and the chunked passes over it: forward, backward, one training epoch, the
//! validation loss and batch prediction, each compiled for AVX-512, AVX2 and baseline x86-64 and
//! chosen at run time. All three do the same arithmetic (see `kernels`), so they agree bit for bit.

use super::kernels::{self, Act, ActFn, Backprop, CHUNK, Linear, Mat, with_act};
use super::lanes::{self, LANES, Lanes, V, multiversion};
use super::optim::RmsProp;
use super::{Activation, Standardizer};

/// The layer widths of a network, inputs first, the single linear output last, and where each
/// layer's parameters sit in the flat parameter vector.
///
/// Parameter layout, layer by layer from the input: the weights `W` row-major with one row per
/// unit (`W[j·n_in + i]` connects input `i` to unit `j`), then the unit biases.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    widths: Vec<usize>,
    activation: Activation,
    offsets: Vec<usize>,
}

impl Shape {
    /// `n_inputs` inputs, the given hidden widths with `activation`, one linear output.
    pub fn new(n_inputs: usize, hidden: &[usize], activation: Activation) -> Shape {
        let mut widths = vec![n_inputs];
        widths.extend_from_slice(hidden);
        widths.push(1);
        let mut offsets = vec![0];
        for w in widths.windows(2) {
            offsets.push(offsets.last().unwrap() + w[1] * w[0] + w[1]);
        }
        Shape { widths, activation, offsets }
    }

    /// Widths from the inputs to the output (`[n_in, hidden…, 1]`).
    #[inline]
    pub fn widths(&self) -> &[usize] {
        &self.widths
    }

    /// The hidden activation.
    pub fn activation(&self) -> Activation {
        self.activation
    }

    /// Number of inputs.
    #[inline]
    pub fn n_inputs(&self) -> usize {
        self.widths[0]
    }

    /// Number of weight layers (hidden layers + 1).
    #[inline]
    pub fn n_layers(&self) -> usize {
        self.widths.len() - 1
    }

    /// Length of the flat parameter vector.
    #[inline]
    pub fn n_params(&self) -> usize {
        *self.offsets.last().unwrap()
    }

    /// Range of layer `l`'s weights (`widths[l+1] × widths[l]`, row-major) in the parameter vector.
    #[inline]
    pub fn weights_range(&self, l: usize) -> std::ops::Range<usize> {
        self.offsets[l]..self.offsets[l] + self.widths[l] * self.widths[l + 1]
    }

    /// Range of layer `l`'s biases in the parameter vector.
    #[inline]
    pub fn bias_range(&self, l: usize) -> std::ops::Range<usize> {
        let start = self.weights_range(l).end;
        start..start + self.widths[l + 1]
    }

    #[inline]
    fn act(&self) -> Act {
        match self.activation {
            Activation::Sigmoid => Act::Sigmoid,
            Activation::Tanh => Act::Tanh,
            Activation::Relu => Act::Relu,
        }
    }

    pub(crate) fn max_width(&self) -> usize {
        self.widths.iter().copied().max().unwrap()
    }

    /// Offset of layer `l`'s outputs in the chunk activation buffer.
    #[inline]
    fn act_offset(&self, l: usize) -> usize {
        self.widths[1..=l].iter().sum::<usize>() * CHUNK
    }
}

/// One layer's parameters as slices.
#[inline(always)]
fn layer<'a>(shape: &Shape, params: &'a [f32], l: usize) -> (&'a [f32], &'a [f32]) {
    (&params[shape.weights_range(l)], &params[shape.bias_range(l)])
}

/// Scratch for one chunk: inputs, targets, activations of every layer, two delta buffers, and
/// the per-lane gradient sums of a batch. Allocated once per fit or prediction call.
pub(crate) struct Work {
    x: Vec<V>,
    y: [V; CHUNK],
    mask: [V; CHUNK],
    acts: Vec<V>,
    delta: Vec<V>,
    delta2: Vec<V>,
    g: Vec<V>,
    grad: Vec<f32>,
}

impl Work {
    pub(crate) fn new(shape: &Shape) -> Work {
        let m = shape.max_width() * CHUNK;
        Work {
            x: vec![V::ZERO; shape.n_inputs() * CHUNK],
            y: [V::ZERO; CHUNK],
            mask: [V::ZERO; CHUNK],
            acts: vec![V::ZERO; shape.act_offset(shape.n_layers())],
            delta: vec![V::ZERO; m],
            delta2: vec![V::ZERO; m],
            g: vec![V::ZERO; shape.n_params()],
            grad: vec![0.0; shape.n_params()],
        }
    }

    /// The gradient of the last batch.
    pub(crate) fn grad(&self) -> &[f32] {
        &self.grad
    }
}

/// Prefetches the training rows the next chunk will gather, a few at a time between kernels: the
/// rows are read in random order from a set larger than L2, and spreading the requests over a
/// chunk's work hides their latency without stalling on the CPU's miss buffers.
struct Prefetch<'a> {
    rows: &'a [f32],
    stride: usize,
    ahead: &'a [u32],
    per_step: usize,
}

impl Prefetch<'_> {
    fn none() -> Prefetch<'static> {
        Prefetch { rows: &[], stride: 0, ahead: &[], per_step: 0 }
    }

    #[inline(always)]
    fn step(&mut self) {
        let (now, later) = self.ahead.split_at(self.per_step.min(self.ahead.len()));
        for &i in now {
            // A hint needs no bounds check (and the indices come from the permutation anyway).
            prefetch(self.rows.as_ptr().wrapping_add(i as usize * self.stride));
        }
        self.ahead = later;
    }
}

/// Asks for the cache line at `p` ahead of use (a hint: no effect on results).
#[inline(always)]
fn prefetch(p: *const f32) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults, whatever the address.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Forward pass of the chunk in `x` (`nv` vectors) into `acts`.
#[inline(always)]
fn forward<L: Lanes>(shape: &Shape, params: &[f32], x: &[V], acts: &mut [V], nv: usize, pf: &mut Prefetch<'_>) {
    let w = shape.widths();
    let n_layers = shape.n_layers();
    for l in 0..n_layers {
        let (din, dout) = (w[l], w[l + 1]);
        let (wts, bias) = layer(shape, params, l);
        let (before, after) = acts.split_at_mut(shape.act_offset(l));
        let inp = if l == 0 { x } else { &before[shape.act_offset(l - 1)..] };
        let out = &mut after[..dout * CHUNK];
        kernels::dense::<L, _>(Mat { w: wts, so: din, sk: 1 }, Some(bias), dout, din, inp, out, nv, Linear);
        if l + 1 < n_layers {
            with_act!(shape.act(), f => kernels::activate::<L, _>(f, out, dout, nv));
        }
        pf.step();
    }
}

/// The network's outputs for the chunk, after [`forward`].
#[inline(always)]
fn outputs<'a>(shape: &Shape, acts: &'a [V]) -> &'a [V] {
    &acts[shape.act_offset(shape.n_layers() - 1)..][..CHUNK]
}

/// Lane sums of `mask·(ŷ − y)²` over the chunk, each lane a fused chain in `v` order; with
/// `delta`, also writes `scale·mask·(ŷ − y)` there (the gradient of the batch MSE at the output).
#[inline(always)]
fn errors<L: Lanes>(yhat: &[V], y: &[V], mask: &[V], nv: usize, mut delta: Option<(&mut [V], f32)>) -> V {
    let mut sse = L::splat(0.0);
    for v in 0..nv {
        let e = L::load(&yhat[v]).sub(L::load(&y[v])).mul(L::load(&mask[v]));
        sse = e.fma(e, sse);
        if let Some((d, scale)) = delta.as_mut() {
            e.mul(L::splat(*scale)).store(&mut d[v]);
        }
    }
    let mut out = V::ZERO;
    sse.store(&mut out);
    out
}

/// Backward pass of a chunk after [`forward`]: adds the gradient of `scale/2 · Σ(ŷ − y)²` to the
/// lane sums `w.g` and returns the lane sums of squared errors (masked rows contribute exactly 0).
#[inline(always)]
fn backward<L: Lanes>(shape: &Shape, params: &[f32], w: &mut Work, scale: f32, nv: usize, pf: &mut Prefetch<'_>) -> V {
    let widths = shape.widths();
    let n_layers = shape.n_layers();
    let act = shape.act();
    let sse = errors::<L>(outputs(shape, &w.acts), &w.y, &w.mask, nv, Some((&mut w.delta, scale)));
    let (mut d, mut d2) = (&mut w.delta, &mut w.delta2);
    for l in (0..n_layers).rev() {
        let (din, dout) = (widths[l], widths[l + 1]);
        let a_in: &[V] = if l == 0 { &w.x } else { &w.acts[shape.act_offset(l - 1)..] };
        let (g_w, g_b) = w.g[shape.weights_range(l).start..].split_at_mut(din * dout);
        kernels::outer::<L>(d, a_in, dout, din, nv, g_w, g_b);
        pf.step();
        if l > 0 {
            let (wts, _) = layer(shape, params, l);
            let m = Mat { w: wts, so: 1, sk: din };
            with_act!(act, f => kernels::dense::<L, _>(m, None, din, dout, d, d2, nv, Backprop { a: a_in, f }));
            pf.step();
            std::mem::swap(&mut d, &mut d2);
        }
    }
    sse
}

/// Adds the lanes of `sse` to `total` in lane order.
#[inline(always)]
fn add_lanes(total: &mut f64, sse: V) {
    for s in sse.0 {
        *total += s as f64;
    }
}

/// Training rows, standardized: inputs then target, `stride` values per row, 64-byte aligned and
/// `stride` a power of two (up to 16) so a row never straddles a cache line. One extra row of
/// zeros, at index `n_rows`, fills the missing lanes of a batch's last vector.
pub(crate) struct TrainSet {
    data: Vec<V>,
    stride: usize,
    n_in: usize,
    n_rows: usize,
}

impl TrainSet {
    fn stride(n_in: usize) -> usize {
        if n_in < LANES { (n_in + 1).next_power_of_two() } else { (n_in + 1).next_multiple_of(LANES) }
    }

    /// Whether `n_rows` rows of `n_in` inputs fit (gathers address values by i32 offsets).
    pub(crate) fn fits(n_rows: usize, n_in: usize) -> bool {
        (n_rows + 1).saturating_mul(TrainSet::stride(n_in)) <= i32::MAX as usize
    }

    /// `n_rows` rows of `n_in` inputs `value(r, k)` and a target `value(r, n_in)`.
    pub(crate) fn new(n_rows: usize, n_in: usize, value: impl Fn(usize, usize) -> f32) -> TrainSet {
        assert!(TrainSet::fits(n_rows, n_in), "{n_rows} rows of {n_in} inputs are too many");
        let stride = TrainSet::stride(n_in);
        let mut set = TrainSet { data: vec![V::ZERO; ((n_rows + 1) * stride).div_ceil(LANES)], stride, n_in, n_rows };
        let vals = set.values_mut();
        for r in 0..n_rows {
            for k in 0..=n_in {
                vals[r * stride + k] = value(r, k);
            }
        }
        set
    }

    #[inline(always)]
    fn values(&self) -> &[f32] {
        // SAFETY: `V` is 16 f32 with no padding (`repr(C)`, size 64).
        unsafe { std::slice::from_raw_parts(self.data.as_ptr().cast::<f32>(), self.data.len() * LANES) }
    }

    fn values_mut(&mut self) -> &mut [f32] {
        // SAFETY: as in `values`.
        unsafe { std::slice::from_raw_parts_mut(self.data.as_mut_ptr().cast::<f32>(), self.data.len() * LANES) }
    }
}

/// Copies rows `idx` (at most one chunk) into the chunk buffers, transposed; missing rows are the
/// zero row, with mask 0.
#[inline(always)]
fn gather<L: Lanes>(set: &TrainSet, idx: &[u32], w: &mut Work) -> usize {
    let (vals, stride, n_in) = (set.values(), set.stride, set.n_in);
    assert!(idx.iter().fold(0, |m, &i| m.max(i)) < set.n_rows as u32);
    assert!(vals.len() >= (set.n_rows + 1) * stride);
    let nv = idx.len().div_ceil(LANES);
    for v in 0..nv {
        let ids = &idx[v * LANES..idx.len().min((v + 1) * LANES)];
        // No overflow: `TrainSet::new` keeps every offset within i32.
        let mut at = [(set.n_rows * stride) as i32; LANES];
        if let Ok(full) = <&[u32; LANES]>::try_from(ids) {
            for (a, &i) in at.iter_mut().zip(full) {
                *a = i as i32 * stride as i32;
            }
            w.mask[v] = V([1.0; LANES]);
        } else {
            let mut mask = V::ZERO;
            for (l, &i) in ids.iter().enumerate() {
                at[l] = i as i32 * stride as i32;
                mask.0[l] = 1.0;
            }
            w.mask[v] = mask;
        }
        if stride == 8 {
            // SAFETY: every offset starts one of the n_rows + 1 rows of 8 values in `vals`.
            let cols = unsafe { L::gather8(vals, &at) };
            for (k, c) in cols[..n_in].iter().enumerate() {
                c.store(&mut w.x[k * CHUNK + v]);
            }
            cols[n_in].store(&mut w.y[v]);
        } else {
            for k in 0..=n_in {
                // SAFETY: every offset starts a row in `vals`, and k < stride.
                let c = unsafe { L::gather(vals, &at) };
                c.store(if k < n_in { &mut w.x[k * CHUNK + v] } else { &mut w.y[v] });
                for a in &mut at {
                    *a += 1;
                }
            }
        }
    }
    nv
}

/// Kernel calls per chunk, each followed by a [`Prefetch::step`]: L forward, 2L − 1 backward.
fn steps_per_chunk(shape: &Shape) -> usize {
    3 * shape.n_layers() - 1
}

/// Gradient of the batch MSE over the rows `perm[range]` into `w.grad`; returns the batch's sum
/// of squared errors. Rows go to lanes in order (row r of the batch to lane r mod 16).
#[inline(always)]
fn batch_gradient<L: Lanes>(
    shape: &Shape,
    params: &[f32],
    set: &TrainSet,
    perm: &[u32],
    range: std::ops::Range<usize>,
    w: &mut Work,
) -> f64 {
    w.g.fill(V::ZERO);
    let scale = 2.0 / range.len() as f32;
    let mut sse = 0.0;
    let per = CHUNK * LANES;
    let per_step = per.div_ceil(steps_per_chunk(shape));
    let mut c0 = range.start;
    while c0 < range.end {
        let c1 = (c0 + per).min(range.end);
        let nv = gather::<L>(set, &perm[c0..c1], w);
        let ahead = &perm[c1..(c1 + per).min(perm.len())];
        let mut pf = Prefetch { rows: set.values(), stride: set.stride, ahead, per_step };
        forward::<L>(shape, params, &w.x, &mut w.acts, nv, &mut pf);
        add_lanes(&mut sse, backward::<L>(shape, params, w, scale, nv, &mut pf));
        c0 = c1;
    }
    for (g, lanes) in w.grad.iter_mut().zip(&w.g) {
        *g = lanes::hsum(lanes);
    }
    sse
}

/// One epoch: a batch gradient and an RMSProp step for each consecutive `batch` rows of `perm`.
/// Returns the sum over batches of each batch's squared errors.
#[inline(always)]
fn epoch_body<L: Lanes>(
    shape: &Shape,
    params: &mut [f32],
    opt: &mut RmsProp,
    set: &TrainSet,
    perm: &[u32],
    batch: usize,
    w: &mut Work,
) -> f64 {
    let mut sse = 0.0;
    let mut b0 = 0;
    while b0 < perm.len() {
        let b1 = (b0 + batch).min(perm.len());
        sse += batch_gradient::<L>(shape, params, set, perm, b0..b1, w);
        opt.step(params, &w.grad);
        b0 = b1;
    }
    sse
}

#[inline(always)]
fn gradient_body<L: Lanes>(shape: &Shape, params: &[f32], set: &TrainSet, idx: &[u32], w: &mut Work) -> f64 {
    batch_gradient::<L>(shape, params, set, idx, 0..idx.len(), w)
}

/// Fixed rows (validation, or a prediction call) already in chunk layout.
pub(crate) struct Chunks {
    /// `n_chunks × n_in × CHUNK` inputs.
    x: Vec<V>,
    /// `n_chunks × CHUNK` targets.
    y: Vec<V>,
    /// `n_chunks × CHUNK` masks (1 for a real row).
    mask: Vec<V>,
    n_in: usize,
    n_rows: usize,
}

impl Chunks {
    /// Lays out `n_rows` rows given by `row(r, k)` (input `k`) and `target(r)`.
    pub(crate) fn new(
        n_rows: usize,
        n_in: usize,
        row: impl Fn(usize, usize) -> f32,
        target: impl Fn(usize) -> f32,
    ) -> Chunks {
        let per = CHUNK * LANES;
        let n_chunks = n_rows.div_ceil(per);
        let mut c = Chunks {
            x: vec![V::ZERO; n_chunks * n_in * CHUNK],
            y: vec![V::ZERO; n_chunks * CHUNK],
            mask: vec![V::ZERO; n_chunks * CHUNK],
            n_in,
            n_rows,
        };
        for r in 0..n_rows {
            let (ch, v, l) = (r / per, (r % per) / LANES, r % LANES);
            for k in 0..n_in {
                c.x[(ch * n_in + k) * CHUNK + v].0[l] = row(r, k);
            }
            c.y[ch * CHUNK + v].0[l] = target(r);
            c.mask[ch * CHUNK + v].0[l] = 1.0;
        }
        c
    }

    fn n_chunks(&self) -> usize {
        self.y.len() / CHUNK
    }

    fn nv(&self, ch: usize) -> usize {
        (self.n_rows - ch * CHUNK * LANES).min(CHUNK * LANES).div_ceil(LANES)
    }
}

/// Sum of squared errors of the network over `set`.
#[inline(always)]
fn sse_body<L: Lanes>(shape: &Shape, params: &[f32], set: &Chunks, w: &mut Work) -> f64 {
    let mut total = 0.0;
    for ch in 0..set.n_chunks() {
        let nv = set.nv(ch);
        forward::<L>(
            shape,
            params,
            &set.x[ch * set.n_in * CHUNK..][..set.n_in * CHUNK],
            &mut w.acts,
            nv,
            &mut Prefetch::none(),
        );
        let r = ch * CHUNK..(ch + 1) * CHUNK;
        add_lanes(&mut total, errors::<L>(outputs(shape, &w.acts), &set.y[r.clone()], &set.mask[r], nv, None));
    }
    total
}

/// Network outputs (standardized scale) for the raw rows `x` (row-major, standardized here by
/// `scale`), into `out`, one chunk at a time.
#[inline(always)]
fn predict_body<L: Lanes>(
    shape: &Shape,
    params: &[f32],
    x: &[f64],
    scale: &[Standardizer],
    w: &mut Work,
    out: &mut [f32],
) {
    let n_in = shape.n_inputs();
    assert!(x.len() == out.len() * n_in && scale.len() == n_in);
    let per = CHUNK * LANES;
    for (c, out) in out.chunks_mut(per).enumerate() {
        let rows = &x[c * per * n_in..][..out.len() * n_in];
        for (r, row) in rows.chunks_exact(n_in).enumerate() {
            for (k, (&v, s)) in row.iter().zip(scale).enumerate() {
                w.x[k * CHUNK + r / LANES].0[r % LANES] = s.apply(v);
            }
        }
        // Lanes past the last row hold stale finite inputs; their outputs are not read.
        forward::<L>(shape, params, &w.x, &mut w.acts, out.len().div_ceil(LANES), &mut Prefetch::none());
        let yhat = outputs(shape, &w.acts);
        for (r, o) in out.iter_mut().enumerate() {
            *o = yhat[r / LANES].0[r % LANES];
        }
    }
}

/// The network laid out for one row at a time, units in lanes: for each layer and block of 16
/// units, one vector per input holding the block's weights (zero beyond the width), then one of
/// biases. A row then costs one fused multiply-add per input and block, and the activation runs
/// on whole blocks; each unit still computes `fma(w, a, acc)` from its bias in input order, as
/// the chunk kernels do, so one-row and batch predictions agree bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RowNet {
    data: Vec<V>,
    /// Per layer: offset in `data`, blocks of outputs, inputs.
    layers: Vec<(usize, usize, usize)>,
    act: Act,
    blocks: usize,
}

impl RowNet {
    pub(crate) fn new(shape: &Shape, params: &[f32]) -> RowNet {
        let w = shape.widths();
        let mut data = Vec::new();
        let mut layers = Vec::new();
        for l in 0..shape.n_layers() {
            let (din, dout) = (w[l], w[l + 1]);
            let (wts, bias) = layer(shape, params, l);
            layers.push((data.len(), dout.div_ceil(LANES), din));
            for b in 0..dout.div_ceil(LANES) {
                let units = b * LANES..dout.min((b + 1) * LANES);
                for i in 0..=din {
                    let mut v = V::ZERO;
                    for (lane, j) in units.clone().enumerate() {
                        v.0[lane] = if i < din { wts[j * din + i] } else { bias[j] };
                    }
                    data.push(v);
                }
            }
        }
        let blocks = shape.max_width().div_ceil(LANES);
        RowNet { data, layers, act: shape.act(), blocks }
    }

    /// Vectors each of the two scratch buffers of [`predict_one`] needs.
    pub(crate) fn blocks(&self) -> usize {
        self.blocks
    }
}

/// One row through `net`: `a` holds the standardized inputs in its lanes (input `i` at
/// `a[i / 16].0[i % 16]`), `b` is scratch; both have `net.blocks()` vectors.
#[inline(always)]
fn row_body<L: Lanes>(net: &RowNet, a: &mut [V], b: &mut [V]) -> f32 {
    with_act!(net.act, f => row_with::<L, _>(f, net, a, b))
}

#[inline(always)]
fn row_with<L: Lanes, F: ActFn>(f: F, net: &RowNet, a: &mut [V], b: &mut [V]) -> f32 {
    assert!(a.len() >= net.blocks && b.len() >= net.blocks);
    let (mut a, mut b) = (a, b);
    let last = net.layers.len() - 1;
    for (l, &(off, blocks, din)) in net.layers.iter().enumerate() {
        let inputs = &a[..din.div_ceil(LANES)];
        for (blk, out) in b[..blocks].iter_mut().enumerate() {
            let w = &net.data[off + blk * (din + 1)..][..din + 1];
            let mut acc = L::load(&w[din]);
            for (i, wi) in w[..din].iter().enumerate() {
                acc = L::load(wi).fma(L::splat(inputs[i / LANES].0[i % LANES]), acc);
            }
            if l < last { f.apply(acc) } else { acc }.store(out);
        }
        std::mem::swap(&mut a, &mut b);
    }
    a[0].0[0]
}

multiversion! {
    /// One training epoch over `perm` (see `epoch_body`).
    #[allow(clippy::too_many_arguments)]
    fn epoch(
        shape: &Shape,
        params: &mut [f32],
        opt: &mut RmsProp,
        set: &TrainSet,
        perm: &[u32],
        batch: usize,
        w: &mut Work
    ) -> f64 = epoch_body
}

multiversion! {
    /// The batch gradient over rows `idx` of `set` into `w.grad`; returns the sum of squared errors.
    fn gradient(shape: &Shape, params: &[f32], set: &TrainSet, idx: &[u32], w: &mut Work) -> f64 = gradient_body
}

multiversion! {
    /// Sum of squared errors over `set`.
    fn sse(shape: &Shape, params: &[f32], set: &Chunks, w: &mut Work) -> f64 = sse_body
}

multiversion! {
    /// Standardized outputs for the raw rows `x`.
    fn predict(
        shape: &Shape,
        params: &[f32],
        x: &[f64],
        scale: &[Standardizer],
        w: &mut Work,
        out: &mut [f32]
    ) -> () = predict_body
}

multiversion! {
    /// One row's standardized output (see `row_body`).
    fn predict_one(net: &RowNet, a: &mut [V], b: &mut [V]) -> f32 = row_body
}

/// Applies `act` to every vector of `buf`, and its backward step to `deltas` (a test hook for
/// comparing the builds).
#[cfg(test)]
#[inline(always)]
fn activate_body<L: Lanes>(act: Activation, buf: &mut [V], deltas: &mut [V]) {
    assert_eq!(deltas.len(), buf.len());
    with_act!(Shape::new(1, &[1], act).act(), f => {
        for (v, d) in buf.iter_mut().zip(deltas.iter_mut()) {
            let a = f.apply(L::load(v));
            a.store(v);
            f.backprop(L::load(d), a).store(d);
        }
    })
}

#[cfg(test)]
multiversion! {
    /// The activation and its backward step over whole buffers.
    fn activate_all(act: Activation, buf: &mut [V], deltas: &mut [V]) -> () = activate_body
}
