// xgauge's SPC page (production/spc_report.h; docs/formats.md, "SPC
// page"): one dimension of one lot. Registers the page kind "spc" for
// report.js, which calls it with its helpers (el, chart, table, ...).
//
// For tests and scripts: tr.alarm[data-rule][data-part] per alarm;
// td.cp and td.cpk with data-value; div.banner.ut-warning when U/T > 1/3;
// one div.chart per chart (individuals, moving range, histogram), each with
// its legend ul.spc-legend[data-chart] of li[data-series] (data-value where
// the entry is a number) showing every series' value without hovering:
// the last point, the centre line and limits, the bins and their rule.
// The page's own style (below) includes a print stylesheet: one chart per
// row, kept whole, the legends printed with their colours.
(function () {
  'use strict';
  window.xgaugeExtraPages = window.xgaugeExtraPages || {};

  const STYLE = `
.spc-legend { list-style: none; display: flex; flex-wrap: wrap; gap: 2px 16px; margin: 4px 0 0 70px;
  padding: 0; font-size: 12px; }
.spc-legend li { display: flex; align-items: center; gap: 5px; white-space: nowrap; }
.spc-legend .swatch { display: inline-block; width: 16px; height: 0; border-top: 3px solid; }
.spc-legend .swatch.dashed { border-top-style: dashed; }
.spc-legend .swatch.point { width: 0; border: 4px solid; border-radius: 50%; }
.spc-legend .swatch.bar { width: 0; border: 6px solid; }
.spc-legend .label { color: var(--muted); }
.spc-legend .value { font-weight: 600; font-variant-numeric: tabular-nums; }
@media print {
  @page { size: A4; margin: 12mm; }
  body { font-size: 12px; }
  main { max-width: none; padding: 0; }
  .charts { grid-template-columns: minmax(0, 1fr); gap: 8px; }
  .chart { break-inside: avoid; }
  .chart .uplot { max-width: 100%; overflow: hidden; }
  .u-cursor-x, .u-cursor-y, .u-cursor-pt, .u-select, .u-legend { display: none !important; }
  .spc-legend, .banner, td.num, .swatch { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
  .banner { border: 1px solid currentColor; }
  h2 { break-after: avoid; }
  tr { break-inside: avoid; }
}`;
  function addStyle() {
    if (document.getElementById('spc-style')) return;
    const style = document.createElement('style');
    style.id = 'spc-style';
    style.textContent = STYLE;
    document.head.append(style);
  }

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
    addStyle();
    // A chart's static legend: [{label, colour, kind ('line', 'dashed',
    // 'point', 'bar'), value (a number or null), text}].
    const legend = (name, entries) => el('ul', { class: 'spc-legend', 'data-chart': name },
      entries.map((e) => el('li', { 'data-series': e.label, 'data-value': isNum(e.value) ? String(e.value) : null },
        el('span', { class: 'swatch ' + (e.kind || 'line'), style: `border-color: ${e.colour}` }),
        el('span', { class: 'label' }, e.label), el('span', { class: 'value' }, e.text))));
    // The series' entry shows the last point; hovering shows the point under
    // the cursor, and leaving the chart the last point again.
    const hover = (list, values, what) => (u) => {
      const item = list.querySelector('li[data-series="' + what + '"] .value');
      const i = u.cursor.idx;
      item.textContent = (i === null || i === undefined || !isNum(values[i]))
        ? lastText(values) : `${fixed(values[i], 4)} at part ${s.parts[i]} (#${i + 1})`;
    };
    const lastIndex = (values) => { let i = values.length - 1; while (i >= 0 && !isNum(values[i])) i--; return i; };
    const lastText = (values) => {
      const i = lastIndex(values);
      return i < 0 ? '–' : `${fixed(values[i], 4)} last, part ${s.parts[i]} (#${i + 1})`;
    };
    const limitEntry = (label, colour, v, kind) => ({ label, colour, kind, value: v, text: isNum(v) ? fixed(v, 4) : 'none' });
    const alarmEntry = (chartName) => {
      const k = s.hits.filter((hit) => hit.chart === chartName).length;
      return { label: 'alarm', colour: '#d62728', kind: 'point', value: k, text: k ? `${k} point${k > 1 ? 's' : ''}` : 'none' };
    };
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
    const individualsLegend = legend('individuals', [
      { label: s.dimension, colour: '#1f77b4', value: s.values[n - 1], text: lastText(s.values) },
      alarmEntry('individuals'),
      limitEntry('CL', '#2ca02c', s.limits.centre),
      limitEntry('UCL', '#ff7f0e', s.limits.upper),
      limitEntry('LCL', '#ff7f0e', s.limits.lower),
      limitEntry('USL', '#7f7f7f', t.upper),
      limitEntry('LSL', '#7f7f7f', t.lower),
    ]);
    chart(charts, `Individuals (${s.unit})`, xs, [
      { label: s.dimension, stroke: '#1f77b4', values: s.values },
      { label: 'alarm', stroke: '#d62728', values: flagged('individuals'), points: true, size: 9 },
      { label: 'CL', stroke: '#2ca02c', values: constant(s.limits.centre), width: 1 },
      { label: 'UCL', stroke: '#ff7f0e', values: constant(s.limits.upper), width: 1 },
      { label: 'LCL', stroke: '#ff7f0e', values: constant(s.limits.lower), width: 1 },
      { label: 'USL', stroke: '#7f7f7f', values: constant(t.upper), width: 1 },
      { label: 'LSL', stroke: '#7f7f7f', values: constant(t.lower), width: 1 },
    ], { xLabel: 'part', xIncrs: wholeParts, yValues: dimensionTicks, legend: false,
      hooks: { setCursor: [hover(individualsLegend, s.values, s.dimension)] } }).append(individualsLegend);
    const movingLegend = legend('moving range', [
      { label: 'MR', colour: '#1f77b4', value: s.moving_ranges[n - 1], text: lastText(s.moving_ranges) },
      alarmEntry('moving range'),
      limitEntry('MR-bar', '#2ca02c', s.limits.mr_centre),
      limitEntry('UCL', '#ff7f0e', s.limits.mr_upper),
    ]);
    chart(charts, `Moving range (${s.unit})`, xs, [
      { label: 'MR', stroke: '#1f77b4', values: s.moving_ranges },
      { label: 'alarm', stroke: '#d62728', values: flagged('moving range'), points: true, size: 9 },
      { label: 'MR-bar', stroke: '#2ca02c', values: constant(s.limits.mr_centre), width: 1 },
      { label: 'UCL', stroke: '#ff7f0e', values: constant(s.limits.mr_upper), width: 1 },
    ], { xLabel: 'part', xIncrs: wholeParts, yValues: dimensionTicks, legend: false,
      hooks: { setCursor: [hover(movingLegend, s.moving_ranges, 'MR')] } }).append(movingLegend);
    // Bins by a rule on the data (spc.json's histogram.rule: Freedman-Diaconis,
    // Scott when the IQR is zero); the tolerance limits drawn over them.
    const hist = s.histogram;
    const ruleNames = { 'freedman-diaconis': 'Freedman–Diaconis', scott: 'Scott', single: 'one value' };
    const histLegend = legend('histogram', [
      { label: 'parts', colour: '#1f77b4', kind: 'bar', value: hist.bins,
        text: `${n} in ${hist.bins} bin${hist.bins > 1 ? 's' : ''} of ${fixed(hist.width, 4)} (${ruleNames[hist.rule] || hist.rule})` },
      limitEntry('LSL', '#d62728', t.lower),
      limitEntry('USL', '#d62728', t.upper),
      limitEntry('nominal', '#7f7f7f', t.nominal, 'dashed'),
    ]);
    chart(charts, `Histogram with the specification limits (${s.unit})`, hist.centres, [
      { label: 'parts', stroke: '#1f77b4', values: hist.counts, bars: true },
    ], {
      xLabel: s.unit,
      xValues: dimensionTicks,
      yRange: [0, Math.max(...hist.counts) + 1],  // bars from zero
      legend: false,
      xRange: [Math.min(hist.centres[0] - hist.width, isNum(t.lower) ? t.lower - hist.width / 2 : Infinity),
        Math.max(hist.centres[hist.centres.length - 1] + hist.width, isNum(t.upper) ? t.upper + hist.width / 2 : -Infinity)],
      hooks: { draw: [lines([{ at: t.lower, colour: '#d62728' }, { at: t.upper, colour: '#d62728' },
        { at: t.nominal, colour: '#7f7f7f', dash: [4, 4] }], 'x')] },
    }).append(histLegend);

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
