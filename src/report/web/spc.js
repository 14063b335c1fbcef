// xgauge's SPC page (production/spc_report.h; docs/formats.md, "SPC
// page"): one dimension of one lot. Registers the page kind "spc" for
// report.js, which calls it with its helpers (el, chart, table, ...).
//
// For tests and scripts: tr.alarm[data-rule][data-part] per alarm;
// td.cp and td.cpk with data-value; div.banner.ut-warning when U/T > 1/3;
// one div.chart per chart (individuals, moving range, histogram).
(function () {
  'use strict';
  window.xgaugeExtraPages = window.xgaugeExtraPages || {};

  // Vertical or horizontal reference lines on a chart's canvas.
  function lines(marks, axis) {
    return (u) => {
      const ctx = u.ctx;
      ctx.save();
      for (const m of marks) {
        if (typeof m.at !== 'number') continue;
        ctx.strokeStyle = m.colour;
        ctx.setLineDash(m.dash || []);
        ctx.lineWidth = 1.5 * devicePixelRatio;
        ctx.beginPath();
        if (axis === 'x') {
          const x = u.valToPos(m.at, 'x', true);
          ctx.moveTo(x, u.bbox.top); ctx.lineTo(x, u.bbox.top + u.bbox.height);
        } else {
          const y = u.valToPos(m.at, 'y', true);
          ctx.moveTo(u.bbox.left, y); ctx.lineTo(u.bbox.left + u.bbox.width, y);
        }
        ctx.stroke();
      }
      ctx.restore();
    };
  }

  // Ticks of a measured dimension: as many decimals as the step between
  // ticks needs (20.05, 20.06, ... rather than 20.1, 20.1, ...).
  function dimensionTicks(u, splits) {
    const step = splits.length > 1 ? Math.abs(splits[1] - splits[0]) : 1;
    const decimals = Math.min(6, Math.max(0, Math.ceil(-Math.log10(step || 1)) + 1));
    return splits.map((v) => v.toFixed(decimals));
  }
  const wholeParts = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000];

  window.xgaugeExtraPages.spc = function (data, root, h) {
    const s = data.spc;
    const { el, chart, table, section, meta, fixed, isNum } = h;
    const n = s.values.length;
    const xs = s.values.map((_, i) => i + 1);
    const flagged = (chartName) => {
      const out = new Array(n).fill(null);
      for (const hit of s.hits) if (hit.chart === chartName) out[hit.index] = chartName === 'individuals' ? s.values[hit.index] : s.moving_ranges[hit.index];
      return out;
    };
    const constant = (v) => new Array(n).fill(isNum(v) ? v : null);
    const t = s.tolerance;

    root.append(el('h1', {}, `SPC: ${s.dimension} of lot ${s.lot}`));
    root.append(meta([
      ['Parts measured', String(n)],
      ['Phase-I baseline', `${s.baseline.description} (${s.baseline.n} values)`],
      ['Centre line', `${fixed(s.limits.centre, 4)} ${s.unit}`],
      ['Control limits', `${fixed(s.limits.lower, 4)} … ${fixed(s.limits.upper, 4)} (σ within ${fixed(s.limits.sigma_within, 5)})`],
      ['Tolerance', isNum(t.lower) ? `${fixed(t.lower, 4)} … ${fixed(t.upper, 4)} ${s.unit}` : 'none'],
    ]));
    const alarms = s.hits.length;
    root.append(el('div', { class: 'banner ' + (alarms ? 'nonconforming' : 'conforms') },
      alarms ? `${alarms} alarm${alarms > 1 ? 's' : ''}: the first at part ${s.hits[0].part} (${s.hits[0].rule})`
        : 'In control: no rule broken'));
    if (s.u_over_t_warning)
      root.append(el('div', { class: 'banner inconclusive ut-warning' },
        `U/T = ${fixed(s.u_over_t, 3)}: the measurement's uncertainty takes more than a third of the tolerance`,
        el('small', {}, 'Verdicts near the limits will often be inconclusive, and the chart shows the gauge as much as the process.')));

    const charts = el('div', { class: 'charts' });
    root.append(section('Control charts', charts));
    chart(charts, `Individuals (${s.unit})`, xs, [
      { label: s.dimension, stroke: '#1f77b4', values: s.values },
      { label: 'alarm', stroke: '#d62728', values: flagged('individuals'), points: true, size: 9 },
      { label: 'CL', stroke: '#2ca02c', values: constant(s.limits.centre), width: 1 },
      { label: 'UCL', stroke: '#ff7f0e', values: constant(s.limits.upper), width: 1 },
      { label: 'LCL', stroke: '#ff7f0e', values: constant(s.limits.lower), width: 1 },
      { label: 'USL', stroke: '#7f7f7f', values: constant(t.upper), width: 1 },
      { label: 'LSL', stroke: '#7f7f7f', values: constant(t.lower), width: 1 },
    ], { xLabel: 'part', xIncrs: wholeParts, yValues: dimensionTicks });
    chart(charts, `Moving range (${s.unit})`, xs, [
      { label: 'MR', stroke: '#1f77b4', values: s.moving_ranges },
      { label: 'alarm', stroke: '#d62728', values: flagged('moving range'), points: true, size: 9 },
      { label: 'MR-bar', stroke: '#2ca02c', values: constant(s.limits.mr_centre), width: 1 },
      { label: 'UCL', stroke: '#ff7f0e', values: constant(s.limits.mr_upper), width: 1 },
    ], { xLabel: 'part', xIncrs: wholeParts, yValues: dimensionTicks });
    const hist = s.histogram;
    chart(charts, `Histogram with the specification limits (${s.unit})`, hist.centres, [
      { label: 'parts', stroke: '#1f77b4', values: hist.counts, bars: true },
    ], {
      xLabel: s.unit,
      xValues: dimensionTicks,
      xRange: [Math.min(hist.centres[0] - hist.width, isNum(t.lower) ? t.lower : Infinity),
        Math.max(hist.centres[hist.centres.length - 1] + hist.width, isNum(t.upper) ? t.upper : -Infinity)],
      hooks: { draw: [lines([{ at: t.lower, colour: '#d62728' }, { at: t.upper, colour: '#d62728' },
        { at: t.nominal, colour: '#7f7f7f', dash: [4, 4] }], 'x')] },
    });

    const rows = s.hits.map((hit) => el('tr', { class: 'alarm', 'data-rule': hit.rule, 'data-part': hit.part },
      el('td', { class: 'num' }, String(hit.position)), el('td', {}, hit.part), el('td', {}, hit.rule),
      el('td', {}, hit.chart), el('td', { class: 'num' }, fixed(hit.value, 4)), el('td', {}, hit.description)));
    root.append(section('Alarms (Western Electric / Nelson rules; the part that completed each pattern)',
      rows.length ? table(['#', 'Part', 'Rule', 'Chart', 'Value', 'Pattern'], rows) : el('p', {}, 'None.')));

    const c = s.capability;
    if (c) {
      const cell = (cls, iv) => el('td', { class: 'num ' + cls, 'data-value': iv.value }, fixed(iv.value, 3));
      const ci = (iv) => el('td', { class: 'num' }, `${fixed(iv.low, 3)} … ${fixed(iv.high, 3)}`);
      root.append(section(`Capability of the baseline (${Math.round(100 * c.confidence)} % confidence intervals)`,
        table(['Index', 'Value', 'Interval'], [
          el('tr', {}, el('td', {}, 'Cp'), cell('cp', c.cp), ci(c.cp)),
          el('tr', {}, el('td', {}, 'Cpk'), cell('cpk', c.cpk), ci(c.cpk)),
        ]),
        el('p', {}, `From the baseline's ${c.n} values: mean ${fixed(c.mean, 4)}, s ${fixed(c.s, 5)} ${s.unit}; ` +
          'Cp from chi-square limits, Cpk by Bissell\'s approximation.'),
        el('p', {}, `U/T (mean U over the tolerance zone's width): ${fixed(s.u_over_t, 3)}`)));
    } else {
      root.append(section('Capability', el('p', {}, 'No tolerance with both limits: no Cp or Cpk.')));
    }
  };
})();
