// xgauge's inspection reports: builds the page from the JSON block that the
// C++ side embeds (report/html.h; docs/formats.md, "report.html"). Three
// kinds, chosen by <html data-report>: measurement, calibration, study
// (and spc, drawn by spc.js).
// Charts are drawn by uPlot (inlined before this script). Nothing is fetched.
//
// For tests and scripts the page marks what it shows:
//   <html data-ready="true"> once drawn (also after an error, which is
//   listed in window.xgaugeErrors and shown at the top);
//   measurement: tr.dimension[data-dimension] with td.value, td.u,
//   td.verdict; figure.residual[data-radiograph][data-scale];
//   study: tr.dimension[data-dimension] with td.mean-abs, td.mean-u,
//   td.coverage; calibration: tr.term[data-term] with td.weight, td.mu.
(function () {
  'use strict';

  // ---- helpers -----------------------------------------------------------

  const SVG = 'http://www.w3.org/2000/svg';

  // el('td', {class: 'num'}, 'text', child...): an element with attributes
  // (dataset keys as data-*) and children (strings become text).
  function el(tag, attrs, ...children) {
    const node = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      node.setAttribute(k, v === true ? '' : String(v));
    }
    for (const c of children.flat(Infinity)) {
      if (c === null || c === undefined || c === false) continue;
      node.append(c instanceof Node ? c : document.createTextNode(String(c)));
    }
    return node;
  }
  function svg(tag, attrs, ...children) {
    const node = document.createElementNS(SVG, tag);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, String(v));
    for (const c of children.flat(Infinity)) if (c) node.append(c);
    return node;
  }
  const isNum = (v) => typeof v === 'number' && isFinite(v);
  const fixed = (v, d) => (isNum(v) ? v.toFixed(d) : '–');
  const signed = (v, d) => (isNum(v) ? (v >= 0 ? '+' : '') + v.toFixed(d) : '–');
  const percent = (v) => (isNum(v) ? (100 * v).toFixed(1) + ' %' : '–');
  const general = (v) => (isNum(v) ? Number(v.toPrecision(4)).toString() : '–');
  // A table; a header is right-aligned when its column's first cell is a number.
  function table(headers, rows, attrs) {
    const first = rows.length ? Array.from(rows[0].children) : [];
    return el('table', attrs || {},
      el('thead', {}, el('tr', {}, headers.map((h, i) =>
        el('th', { class: first[i] && first[i].classList.contains('num') ? 'num' : null }, h)))),
      el('tbody', {}, rows));
  }
  function section(title, ...children) {
    return el('section', {}, el('h2', {}, title), children);
  }
  function meta(pairs) {
    const dl = el('dl', { class: 'meta' });
    for (const [k, v] of pairs) {
      if (v === null || v === undefined || v === '') continue;
      dl.append(el('dt', {}, k), el('dd', {}, v));
    }
    return dl;
  }
  function basename(path) {
    return String(path || '').split('/').pop();
  }
  function palette(i) {
    const colours = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf',
      '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22'];
    return colours[i % colours.length];
  }
  // Axis labels with the few digits that tell ticks apart (uPlot's default
  // shows 0.0015 as 0.001); tiny values of a log axis in exponent form.
  function tickLabel(v) {
    if (v === null || v === undefined) return '';
    if (v !== 0 && Math.abs(v) < 1e-3) return v.toExponential(1).replace(/\.0e/, 'e');
    return String(Number(v.toPrecision(3)));
  }
  function chartWidth(container) {
    return Math.max(320, Math.floor(container.getBoundingClientRect().width || 560));
  }

  // A uPlot chart in `container`; series: [{label, stroke, points, width}].
  function chart(container, title, xs, series, opts) {
    opts = opts || {};
    const box = el('div', { class: 'chart' }, el('h4', {}, title));
    container.append(box);
    const width = opts.width || chartWidth(container.classList.contains('charts') ? box : container);
    const options = {
      width: width,
      height: opts.height || 260,
      scales: {
        x: Object.assign({ time: false }, opts.xRange ? { range: opts.xRange } : {}),
        y: Object.assign(opts.logY ? { distr: 3 } : {}, opts.yRange ? { range: opts.yRange } : {}),
      },
      axes: [Object.assign({ label: opts.xLabel || '' }, opts.xIncrs ? { incrs: opts.xIncrs } : {},
        opts.xValues ? { values: opts.xValues } : {}),
        { label: opts.yLabel || '', size: 70, values: opts.yValues || ((u, splits) => splits.map(tickLabel)) }],
      legend: { show: opts.legend !== false },
      series: [{ label: opts.xLabel || 'x' }].concat(series.map((s) => {
        const out = {
          label: s.label,
          stroke: s.stroke,
          width: s.points ? 0 : (s.width === undefined ? 1.5 : s.width),
          points: s.points ? { show: true, size: s.size || 5, fill: s.stroke, stroke: s.stroke } : { show: false },
          spanGaps: false,
        };
        if (s.bars) {
          out.paths = uPlot.paths.bars({ size: [0.9, 60] });
          out.fill = s.stroke + '99';
        }
        return out;
      })),
      hooks: opts.hooks || {},
      cursor: { drag: { x: true, y: false } },
    };
    new uPlot(options, [xs].concat(series.map((s) => s.values)), box);
    return box;
  }

  // A radiograph picture: the image placed in detector pixel coordinates,
  // with optional outline segments, residual regions and marked boxes.
  function picture(p, cls, caption, overlay) {
    const [x, y, w, h] = p.at;
    const root = svg('svg', { viewBox: `${x} ${y} ${w} ${h}`, preserveAspectRatio: 'xMidYMid meet' });
    root.append(svg('image', { href: p.uri, x: x, y: y, width: w, height: h, preserveAspectRatio: 'none' }));
    if (overlay) overlay(root);
    const attrs = { class: 'picture ' + cls };
    return el('figure', attrs, root, el('figcaption', {}, caption));
  }
  function outlineOverlay(segments) {
    return (root) => {
      const g = svg('g', { class: 'outline' });
      for (const s of segments || []) g.append(svg('line', { x1: s[0], y1: s[1], x2: s[2], y2: s[3] }));
      root.append(g);
    };
  }
  function regionsOverlay(regions) {
    return (root) => {
      const g = svg('g', { class: 'regions' });
      for (const r of regions) {
        const [x, y, w, h] = r.box_px;
        const pad = 3;
        g.append(svg('rect', { x: x - pad, y: y - pad, width: w + 2 * pad, height: h + 2 * pad }));
      }
      root.append(g);
    };
  }
  function colourBar(scale, stops) {
    const gradient = 'linear-gradient(to right, ' + stops.join(', ') + ')';
    const ticks = el('div', { class: 'ticks' });
    for (const f of [-1, -0.5, 0, 0.5, 1]) {
      ticks.append(el('span', { style: `left: ${50 + 50 * f}%` }, (f > 0 ? '+' : '') + general(f * scale)));
    }
    return el('div', { class: 'colourbar', 'data-scale': scale },
      el('div', {}, 'residual, simulated − measured (normalized intensity):'),
      el('div', {}, el('div', { class: 'bar', style: 'background: ' + gradient }), ticks),
      el('div', { class: 'note' }, 'blue: measured brighter than the model; red: darker'));
  }

  // The three pictures of each radiograph of a fit, one shared colour bar.
  function radiographSections(pictures, regions, checks) {
    const out = [];
    out.push(colourBar(pictures.residual_scale, pictures.colour_map));
    for (const r of pictures.radiographs) {
      const mine = (regions || []).filter((g) => g.radiograph === r.name);
      const check = (checks || []).find((c) => c.name === r.name);
      const heading = el('h3', {}, 'Radiograph ' + r.name);
      const figures = el('div', { class: 'pictures' },
        picture(r.measured, 'measured', 'measured (normalized), fitted outline in cyan',
          outlineOverlay(r.outline)),
        picture(r.simulated, 'simulated', 'simulated at the fitted dimensions and pose'),
        (() => {
          const f = picture(r.residual, 'residual',
            `residual; colour scale ±${general(r.residual_scale)}` +
            (mine.length ? `; ${mine.length} residual region(s) boxed` : ''),
            regionsOverlay(mine));
          f.dataset.radiograph = r.name;
          f.dataset.scale = String(r.residual_scale);
          return f;
        })());
      const figures_note = check ? el('p', { class: 'note' },
        `rms residual ${general(check.rms_residual)}, open-beam noise σ ${general(check.noise_sigma)}, ` +
        `ratio ${general(check.misfit_ratio)} (1 for a fit that leaves only noise)`) : null;
      out.push(heading, figures, figures_note);
    }
    return out;
  }

  // ---- measurement -------------------------------------------------------

  const verdictClass = { 'conforms': 'conforms', 'inconclusive': 'inconclusive', 'does not conform': 'nonconforming' };

  function measurementPage(data, root) {
    const result = data.result;
    const ctx = data.context || {};
    const part = ctx.part || {};
    const truth = data.truth || null;

    root.append(el('h1', {}, 'Measurement of ' + basename(part.file || 'the part')));
    root.append(el('p', { class: 'subtitle' }, part.description || ''));
    const machine = (ctx.machine || {}).settings || {};
    const detector = machine.detector || {};
    const material = (ctx.material || {}).curve || {};
    root.append(meta([
      ['Job', result.job], ['Written', data.generated],
      ['Part model', part.file], ['Software', result.software],
      ['Machine', `${basename((ctx.machine || {}).file)}: ${detector.columns} × ${detector.rows} px of ` +
        `${(detector.pixel_pitch_mm || []).join(' × ')} mm, source–detector ${machine.source_detector_distance_mm} mm`],
      ['Schedule', `${result.schedule}, ${result.loss} loss`],
      ['Material', `${basename((ctx.material || {}).file)}: ${(material.terms || []).length} exponentials` +
        (material.description ? ` (${material.description})` : '')],
      ['Time', `${fixed(result.seconds, 1)} s, ${result.evaluations} evaluations`],
    ]));

    // The overall verdict first: what a reader needs most. A fit the
    // acceptance rule refused is no measurement: its values are shown as
    // the rejected fit's, with why.
    const measured = result.status !== 'not measured';
    const dimensions = (measured ? result.dimensions : result.rejected_dimensions) || [];
    const judged = dimensions.filter((d) => d.verdict);
    const count = (v) => judged.filter((d) => d.verdict === v).length;
    let banner;
    if (!measured) {
      banner = el('div', { class: 'banner nonconforming' },
        `Not measured: the fit does not explain the radiographs (${result.attempts} attempt(s)); ` +
        'the values below are the rejected fit\'s, not results, and no verdict is given',
        el('ul', {}, (result.failures || []).map((f) => el('li', {}, f))));
    } else if (judged.length === 0) {
      banner = el('div', { class: 'banner neutral' }, `${dimensions.filter((d) => d.free).length} dimensions measured; no tolerances given`);
    } else if (count('does not conform') > 0) {
      banner = el('div', { class: 'banner nonconforming' }, `Does not conform: ${count('does not conform')} of ${judged.length} toleranced dimensions outside their zone`);
    } else if (count('inconclusive') > 0) {
      banner = el('div', { class: 'banner inconclusive' }, `Inconclusive: ${count('inconclusive')} of ${judged.length} toleranced dimensions within U of a limit`);
    } else {
      banner = el('div', { class: 'banner conforms' }, `Conforms: all ${judged.length} toleranced dimensions inside their zone shrunk by U`);
    }
    if (result.decision_rule) banner.append(el('small', {}, result.decision_rule));
    root.append(banner);

    // Warnings that name a dimension go beside its row; the rest above the table.
    const names = dimensions.map((d) => d.name);
    const byDimension = {};
    const general_warnings = [];
    for (const w of result.warnings || []) {
      const hit = names.find((n) => new RegExp('(^|[^A-Za-z0-9_])' + n + '($|[^A-Za-z0-9_])').test(w));
      if (hit) (byDimension[hit] = byDimension[hit] || []).push(w);
      else general_warnings.push(w);
    }
    if (general_warnings.length)
      root.append(el('div', { class: 'warnings' }, el('strong', {}, 'Warnings'),
        el('ul', {}, general_warnings.map((w) => el('li', {}, w)))));

    const headers = ['Dimension', 'Nominal', 'Measured', 'Deviation', 'Tolerance zone', 'U (k = 2)', 'U is', 'Verdict'];
    if (truth) headers.push('True', 'Error');
    headers.push('Notes');
    const rows = dimensions.map((d) => {
      // Deviations only from a nominal the job or its tolerance states; the
      // part model's default is another part number's start value.
      const nom = isNum(d.nominal) ? d.nominal : d.tolerance ? d.tolerance.nominal : undefined;
      const unit = d.unit === 'deg' ? '°' : '';
      const cells = [
        el('td', {}, d.name + (d.free ? '' : ' (fixed)')),
        el('td', { class: 'num' }, fixed(nom, 4) + unit),
        el('td', { class: 'num value', 'data-value': d.value_mm }, fixed(d.value_mm, 4) + unit),
        el('td', { class: 'num' }, isNum(nom) ? signed(d.value_mm - nom, 4) : '–'),
        el('td', { class: 'num' }, d.tolerance
          ? `${fixed(d.tolerance.nominal + d.tolerance.lower, 4)} … ${fixed(d.tolerance.nominal + d.tolerance.upper, 4)}`
          : ''),
        el('td', { class: 'num u', 'data-u': isNum(d.expanded_uncertainty) ? d.expanded_uncertainty : null },
          !d.free ? '' : isNum(d.expanded_uncertainty) ? fixed(d.expanded_uncertainty, 4) : 'not identifiable'),
        // Verified: by substitution on a calibrated master (docs/method.md,
        // "Verification on a master"); unverified: the model's budget alone.
        el('td', { class: 'basis' + (d.free && !d.verified ? ' unverified' : '') },
          !d.free ? '' : d.verified ? 'verified' : 'unverified'),
        el('td', { class: 'verdict ' + (verdictClass[d.verdict] || '') }, d.verdict || ''),
      ];
      if (truth) {
        const t = truth[d.name];
        cells.push(el('td', { class: 'num' }, fixed(t, 4)), el('td', { class: 'num' }, isNum(t) ? signed(d.value_mm - t, 4) : '–'));
      }
      cells.push(el('td', { class: 'notes' }, (byDimension[d.name] || []).join(' ')));
      return el('tr', { class: 'dimension' + (d.free ? '' : ' fixed'), 'data-dimension': d.name }, cells);
    });
    root.append(section('Dimensions', table(headers, rows, { id: 'dimensions' }),
      el('p', { class: 'note' }, 'Values in mm (° for angles). U is the expanded uncertainty with coverage factor 2 ' +
        '(about 95 %): verified, by substitution on a calibrated master of this part type (ISO 15530-3), the value ' +
        'corrected by the method\'s bias found there; unverified, from the model\'s budget below alone, which no ' +
        'measurement of a known part has checked. Deviation = measured − nominal, where the job or a tolerance ' +
        'states the nominal.')));

    const u = (measured ? result.uncertainty : result.rejected_uncertainty) || {};
    if ((u.combinations || []).length) {
      root.append(el('h3', {}, 'Measurable combinations'),
        el('p', { class: 'note' }, "The part model's named combinations (a drawing's widths), and dimensions the radiographs cannot separate whose combination they do measure."),
        table(['Combination', 'Value', 'U (k = 2)'], u.combinations.map((c) =>
          el('tr', {}, el('td', {}, c.name ? `${c.name} = ${c.expression}` : c.expression), el('td', { class: 'num' }, fixed(c.value, 4)),
            el('td', { class: 'num' }, fixed(c.expanded_uncertainty, 4))))));
    }
    if ((u.dimensions || []).length) {
      const details = el('details', {}, el('summary', {}, 'Uncertainty budget, component by component'),
        el('p', { class: 'note' }, `${u.method}; coverage factor ${u.coverage_factor}. ` + (u.notes || []).join(' ')));
      for (const b of u.dimensions) {
        details.append(el('h3', {}, `${b.name}: U = ${isNum(b.expanded_uncertainty) ? fixed(b.expanded_uncertainty, 4) : 'not identifiable'}`),
          table(['Component', 'Quantity', 'u(quantity)', 'Sensitivity', 'Contribution (mm)'],
            b.components.map((c) => el('tr', {},
              el('td', {}, c.name), el('td', {}, c.quantity),
              el('td', { class: 'num' }, `${general(c.standard_uncertainty)} ${c.unit || ''}`),
              el('td', { class: 'num' }, general(c.sensitivity)),
              el('td', { class: 'num' }, fixed(c.contribution, 5))))));
      }
      root.append(details);
    }

    root.append(section('Radiographs', radiographSections(data.pictures, result.residual_regions, result.fit_checks)));
    const regions = result.residual_regions || [];
    if (regions.length) {
      root.append(el('h3', {}, 'Residual regions'),
        el('p', { class: 'note' }, 'Where the radiograph differs from the fitted model by more than the noise explains: a defect, or a part that differs from its model.'),
        table(['Radiograph', 'Centre (px)', 'Box (px)', 'Area (mm²)', 'Peak', 'σ', 'Sign', 'In the part (mm)'],
          regions.map((r) => el('tr', {},
            el('td', {}, r.radiograph),
            el('td', { class: 'num' }, r.centre_px.map((v) => v.toFixed(1)).join(', ')),
            el('td', { class: 'num' }, r.box_px.join(', ')),
            el('td', { class: 'num' }, general(r.area_mm2)),
            el('td', { class: 'num' }, general(r.peak)),
            el('td', { class: 'num' }, general(r.sigmas)),
            el('td', {}, r.sign),
            el('td', { class: 'num' }, r.part_mm ? r.part_mm.map((v) => v.toFixed(2)).join(', ') : '–')))), { class: 'regions' });
    }

    const fitSection = section('The fit');
    root.append(fitSection);
    lossChart(fitSection, result.stages);
    fitSection.append(table(['Stage', 'Method', 'Level', 'Samples', 'Evaluations', 'Seconds', 'Loss before', 'Loss after', 'Termination'],
      result.stages.map((s) => el('tr', {},
        el('td', {}, s.name), el('td', {}, s.method), el('td', { class: 'num' }, s.level),
        el('td', { class: 'num' }, s.samples), el('td', { class: 'num' }, s.evaluations),
        el('td', { class: 'num' }, fixed(s.seconds, 2)), el('td', { class: 'num' }, general(s.loss_before)),
        el('td', { class: 'num' }, general(s.loss_after)), el('td', { class: 'note' }, s.termination)))));
    fitSection.append(table(['Radiograph', 'Pattern', 'Loss', 'Rotation (°)', 'Translation (mm)'],
      result.radiographs.map((r) => el('tr', {},
        el('td', {}, r.name), el('td', {}, r.pattern), el('td', { class: 'num' }, general(r.loss)),
        el('td', { class: 'num' }, (r.pose.rotation_deg || []).map((v) => v.toFixed(3)).join(', ')),
        el('td', { class: 'num' }, (r.pose.translation_mm || []).map((v) => v.toFixed(3)).join(', '))))));
    inputsList(root, result.inputs_sha256);
  }

  // The loss at every evaluation, one series per stage, on a log axis: the
  // stages work on different levels and objectives, so each has its own line.
  function lossChart(container, stages) {
    let total = 0;
    const spans = stages.map((s) => {
      const n = Math.max((s.trace || []).length, 1);
      const span = { start: total, n: n, trace: s.trace || [] };
      total += n;
      return span;
    });
    if (total < 2) return;
    const xs = Array.from({ length: total }, (_, i) => i);
    const series = stages.map((s, k) => {
      const values = new Array(total).fill(null);
      spans[k].trace.forEach((v, i) => { values[spans[k].start + i] = isNum(v) && v > 0 ? v : null; });
      return { label: `${k + 1}. ${s.name}`, stroke: palette(k), values: values, points: spans[k].trace.length < 40, size: 4 };
    });
    chart(container, 'Loss by stage and evaluation (least-squares stages: by iteration)', xs, series,
      { xLabel: 'evaluation', yLabel: 'loss', logY: true, height: 300 });
  }

  function inputsList(root, hashes) {
    if (!hashes) return;
    root.append(el('details', {}, el('summary', {}, 'Inputs and their SHA-256'),
      table(['File', 'SHA-256'], Object.entries(hashes).map(([f, h]) =>
        el('tr', {}, el('td', {}, f), el('td', { class: 'mono' }, h))))));
  }

  // ---- calibration -------------------------------------------------------

  function materialCurve(material) {
    const terms = material.terms || [];
    return (x) => terms.reduce((sum, t) => sum + t.weight * Math.exp(-t.mu_per_mm * x), 0);
  }

  // A calibration that failed: the step and the error first, then what the
  // steps found (failed_calibration.json holds the same).
  function failedCalibrationPage(data, root) {
    const f = data.failure;
    root.append(el('h1', {}, 'Calibration failed'));
    root.append(el('p', { class: 'subtitle' }, f.job || ''));
    root.append(el('div', { class: 'banner nonconforming', id: 'failure' }, `Failed at the step “${f.step}”`,
      el('small', {}, f.error)));
    root.append(meta([['Job', f.job], ['Radiograph', f.radiograph], ['Software', f.software], ['Written', data.generated]]));
    const ramp = f.ramp;
    root.append(section('What the steps found',
      f.kind === 'wedge' ? el('p', {}, ramp
        ? `A ramp in columns ${ramp.columns.join(' … ')} (${ramp.automatic_columns ? 'found' : 'given'}), thin end at row ${fixed(ramp.thin_end_row, 2)}, thick end at row ${fixed(ramp.thick_end_row, 2)} (${ramp.automatic_rows ? 'found' : 'given'}).`
        : 'No ramp.') : null,
      f.kind === 'part' ? el('p', {}, (f.initial
        ? `The initial material (thesis eq. 3.8): I1 = ${fixed(f.initial.intensity, 4)}, μ1 = ${fixed(f.initial.mu_per_mm, 4)} /mm. `
        : 'No initial material. ') + `${(f.rounds || []).length} round(s) done; ${(f.poses || []).length} pose(s) fitted.`) : null,
      el('p', {}, `${f.table.path_mm.length} rows in the intensity table; ${f.fit ? f.fit.fits.length : 0} curve fits tried.`)));
    if (f.table.path_mm.length > 1) {
      const box = el('div', {});
      root.append(box);
      chart(box, 'The intensity table (path as fitted)', f.table.path_mm, [
        { label: 'rows of the ramp', stroke: '#1f77b4', points: true, size: 4, values: f.table.transmission }],
      { xLabel: 'path length x (mm)', yLabel: 'I(x)', legend: false });
    }
    if (f.fit)
      root.append(table(['Terms asked', 'Terms used', 'rms', 'max |r|', 'max |r|/I'], f.fit.fits.map((t) => el('tr', {},
        el('td', { class: 'num' }, t.terms_asked), el('td', { class: 'num' }, t.terms_used),
        el('td', { class: 'num' }, general(t.rms_residual)), el('td', { class: 'num' }, general(t.max_abs_residual)),
        el('td', { class: 'num' }, general(t.max_relative_residual))))));
    wedgePicture(root, data.pictures, ramp);
  }

  function wedgePicture(root, pictures, ramp) {
    if (!pictures || pictures.kind !== 'wedge') return;
    const r = pictures.radiographs[0];
    const colours = ['#00d0ff', '#ffd400'];
    const legend = r.marks.map((m, k) => `${m.label} (${k === r.marks.length - 1 ? 'yellow' : 'cyan'})`).join(', ');
    root.append(section('The radiograph', el('div', { class: 'pictures single' },
      picture(r.measured, 'measured', `${r.name}, normalized${pictures.scatter_removed ? ', scatter removed' : ''}: ${legend}`, (svgRoot) => {
        const g = svg('g', { class: 'marks' });
        r.marks.forEach((m, k) => g.append(svg('rect', { x: m.box[0], y: m.box[1], width: m.box[2], height: m.box[3],
          stroke: colours[k === r.marks.length - 1 ? 1 : 0] })));
        svgRoot.append(g);
      })),
    ramp ? meta([['Ramp columns', (ramp.columns || []).join(' … ') + (ramp.automatic_columns ? ' (found)' : ' (given)')],
      ['Thin end row', fixed(ramp.thin_end_row, 2)], ['Thick end row', fixed(ramp.thick_end_row, 2)],
      ['Row noise', general(ramp.row_noise)]]) : null));
  }

  function calibrationPage(data, root) {
    if (data.failure) return failedCalibrationPage(data, root);
    const cal = data.calibration;
    const kind = cal.kind === 'wedge' ? 'wedge' : 'known part';
    root.append(el('h1', {}, `Material calibration from a ${kind}`));
    root.append(el('p', { class: 'subtitle' }, cal.job || ''));
    const curve = materialCurve(data.material);
    const terms = data.material.terms || [];
    const formula = 'I(x) = ' + terms.map((t) => `${t.weight.toFixed(5)} exp(−${t.mu_per_mm.toFixed(5)} x)`).join(' + ');
    const against = cal.against_true_curve;
    root.append(meta([
      ['Job', cal.job], ['Written', data.generated],
      ['Software', cal.software], ['Time', isNum(cal.seconds) ? fixed(cal.seconds, 1) + ' s' : ''],
      ['Calibrated range', `0 … ${fixed(data.data.x_max_mm, 2)} mm of material`],
      ['Data points', String(data.data.path_mm.length)],
    ]));
    root.append(el('div', { class: 'banner neutral' }, formula,
      el('small', {}, `rms residual against the data ${general(cal.material_vs_data.rms_residual)}, largest ${general(cal.material_vs_data.max_abs_residual)}` +
        (against ? `; largest deviation from the true curve ${general(against.max_abs_deviation)} at ${fixed(against.at_mm, 2)} mm` : ''))));

    root.append(section('Material', table(['Term', 'Weight', 'μ (1/mm)'], terms.map((t, k) =>
      el('tr', { class: 'term', 'data-term': k },
        el('td', {}, String(k + 1)), el('td', { class: 'num weight' }, t.weight.toFixed(6)),
        el('td', { class: 'num mu' }, t.mu_per_mm.toFixed(6)))), { id: 'material' })));

    // Charts: data with the curve; residual; deviation from the truth.
    const charts = el('div', { class: 'charts' });
    root.append(section('Curve and residual', charts));
    const px = data.data.path_mm, py = data.data.transmission;
    const xMax = Math.max(data.data.x_max_mm, ...px) * 1.05;
    const dense = Array.from({ length: 401 }, (_, i) => (xMax * i) / 400);
    // One x axis for data and curves: the union, sorted (uPlot needs one x array).
    const xs = Array.from(new Set(px.concat(dense))).sort((a, b) => a - b);
    const at = new Map(px.map((x, i) => [x, py[i]]));
    const truth = data.true_curve;
    const trueAt = truth ? (x) => interpolate(truth.path_mm, truth.transmission, x) : null;
    const series = [
      { label: 'data', stroke: '#1f77b4', points: true, size: 4, values: xs.map((x) => (at.has(x) ? at.get(x) : null)) },
      { label: `fitted (${terms.length} exponentials)`, stroke: '#d62728', values: xs.map(curve) },
    ];
    if (trueAt) series.push({ label: 'true curve (simulation)', stroke: '#7f7f7f', values: xs.map(trueAt) });
    chart(charts, 'Transmission I(x) against path length', xs, series, { xLabel: 'path length x (mm)', yLabel: 'I(x)' });
    chart(charts, 'Residual: data − fit', px, [
      { label: 'data − fit', stroke: '#1f77b4', points: true, size: 4, values: px.map((x, i) => py[i] - curve(x)) }],
    { xLabel: 'path length x (mm)', yLabel: 'data − I(x)' });
    if (trueAt)
      chart(charts, 'Fit − true curve', dense, [
        { label: 'fit − true', stroke: '#d62728', values: dense.map((x) => curve(x) - trueAt(x)) }],
      { xLabel: 'path length x (mm)', yLabel: 'I(x) − true' });

    const fits = (cal.fit || {}).fits || [];
    if (fits.length)
      root.append(el('h3', {}, 'Fits tried'), table(['Terms asked', 'Terms used', 'rms', 'max |r|', 'max |r|/I'],
        fits.map((f) => el('tr', {},
          el('td', { class: 'num' }, f.terms_asked + (f.terms_asked === cal.fit.chosen_terms ? ' (chosen)' : '')),
          el('td', { class: 'num' }, f.terms_used), el('td', { class: 'num' }, general(f.rms_residual)),
          el('td', { class: 'num' }, general(f.max_abs_residual)), el('td', { class: 'num' }, general(f.max_relative_residual))))),
      el('p', { class: 'note' }, cal.fit.choice || ''));

    const pictures = data.pictures;
    if (pictures && pictures.kind === 'wedge') {
      wedgePicture(root, pictures, cal.ramp);
    } else if (pictures && pictures.kind === 'part') {
      root.append(section('The last pose fit', radiographSections(pictures, [], [])));
      const rounds = cal.rounds || [];
      if (rounds.length)
        root.append(el('h3', {}, 'Rounds'), table(['Round', 'rms residual', 'max |r|', 'Change', 'Pose loss', 'Pixels'],
          rounds.map((r, k) => el('tr', {}, el('td', { class: 'num' }, k + 1), el('td', { class: 'num' }, general(r.rms_residual)),
            el('td', { class: 'num' }, general(r.max_abs_residual)), el('td', { class: 'num' }, general(r.change)),
            el('td', { class: 'num' }, general(r.pose_loss)), el('td', { class: 'num' }, r.pixels)))));
    }
  }

  function interpolate(xs, ys, x) {
    if (x <= xs[0]) return ys[0];
    let lo = 0, hi = xs.length - 1;
    if (x >= xs[hi]) return ys[hi];
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (xs[mid] <= x) lo = mid; else hi = mid;
    }
    const t = (x - xs[lo]) / (xs[hi] - xs[lo]);
    return ys[lo] + t * (ys[hi] - ys[lo]);
  }

  // ---- study -------------------------------------------------------------

  function studyPage(data, root) {
    const study = data.study;
    const runs = study.runs || [];
    const dims = Object.keys(study.dimensions || {});
    root.append(el('h1', {}, 'Study of ' + basename(study.dataset)));
    root.append(el('p', { class: 'subtitle' }, `${runs.length} measurements (${study.combinations}) against the dataset's truth`));
    const refused = runs.filter((r) => r.status === 'not measured');
    if (refused.length)
      root.append(el('div', { class: 'warnings' },
        el('strong', {}, `${runs.length - refused.length} of ${runs.length} runs measured; the figures are theirs. Not measured:`),
        el('ul', {}, refused.map((r) => el('li', {}, `${r.id}: ${(r.failures || [])[0] || ''}`)))));
    const pooled = study.pooled_coverage || {};
    root.append(meta([
      ['Dataset', study.dataset], ['Written', data.generated],
      ['Settings', (data.settings || {}).file], ['Median time', fixed(study.median_seconds, 1) + ' s per measurement'],
      ['Mean |error|', fixed(study.mean_abs_mm, 4) + ' mm'], ['Max |error|', fixed(study.max_abs_mm, 4) + ' mm'],
    ]));
    const inBand = isNum(pooled.coverage) && pooled.coverage >= 0.9;
    root.append(el('div', { class: 'banner ' + (pooled.runs_with_u ? (inBand ? 'conforms' : 'inconclusive') : 'neutral') },
      pooled.runs_with_u ? `Pooled coverage ${percent(pooled.coverage)}: the share of |error| ≤ U over ${pooled.runs_with_u} values (about 95 % expected for k = 2)` : 'No uncertainties reported',
      el('small', {}, `mean U ${fixed(pooled.mean_u_mm, 4)} mm, mean |error| ${fixed(pooled.mean_abs_mm, 4)} mm, mean |error|/U ${fixed(pooled.mean_normalised_error, 2)}`)));

    root.append(section('Dimensions', table(['Dimension', 'Runs with U', 'Mean |error|', 'Max |error|', 'Mean U', 'Coverage', 'Mean |e|/U'],
      dims.map((name) => {
        const d = study.dimensions[name];
        return el('tr', { class: 'dimension', 'data-dimension': name },
          el('td', {}, name), el('td', { class: 'num' }, d.runs_with_u),
          el('td', { class: 'num mean-abs' }, fixed(d.mean_abs_mm, 4)), el('td', { class: 'num' }, fixed(d.max_abs_mm, 4)),
          el('td', { class: 'num mean-u' }, fixed(d.mean_u_mm, 4)), el('td', { class: 'num coverage' }, percent(d.coverage)),
          el('td', { class: 'num' }, fixed(d.mean_normalised_error, 2)));
      }), { id: 'dimensions' }),
    el('p', { class: 'note' }, 'Errors in mm (measured − true). Coverage: the share of runs whose |error| is at most the U they reported.')));
    const combos = Object.entries(study.combinations_coverage || {});
    if (combos.length)
      root.append(el('h3', {}, 'Measurable combinations'), table(['Combination', 'Runs', 'Mean |error|', 'Mean U', 'Coverage'],
        combos.map(([e, c]) => el('tr', {}, el('td', {}, e), el('td', { class: 'num' }, c.runs_with_u),
          el('td', { class: 'num' }, fixed(c.mean_abs_mm, 4)), el('td', { class: 'num' }, fixed(c.mean_u_mm, 4)),
          el('td', { class: 'num' }, percent(c.coverage))))));

    // Every run's error with its U as an error bar, one chart per dimension.
    const charts = el('div', { class: 'charts' });
    root.append(section('Errors and uncertainties, run by run', charts));
    const xs = runs.map((_, i) => i + 1);
    for (const name of dims) {
      const errors = runs.map((r) => (r.error_mm || {})[name]);
      const us = runs.map((r) => (r.expanded_uncertainty_mm || {})[name]);
      // The bars' ends as invisible series, so that the y range holds them.
      const end = (sign) => errors.map((e, i) => (isNum(e) && isNum(us[i]) ? e + sign * us[i] : null));
      chart(charts, `${name}: error ± U (k = 2), mm`, xs, [
        { label: 'error (mm)', stroke: '#1f77b4', points: true, size: 6, values: errors.map((v) => (isNum(v) ? v : null)) },
        { label: 'error − U', stroke: 'rgba(0,0,0,0)', values: end(-1), width: 0 },
        { label: 'error + U', stroke: 'rgba(0,0,0,0)', values: end(1), width: 0 },
      ], {
        xLabel: 'run', yLabel: 'error (mm)', height: 220, legend: false,
        xRange: [0.5, runs.length + 0.5], xIncrs: [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000],
        xValues: (u, splits) => splits.map((v) => (runs[v - 1] ? runs[v - 1].id : '')),
        hooks: { draw: [(u) => errorBars(u, errors, us)] },
      });
    }

    // Runtime distribution.
    const seconds = runs.map((r) => r.seconds).filter(isNum);
    if (seconds.length) {
      const lo = Math.min(...seconds), hi = Math.max(...seconds);
      const bins = Math.max(1, Math.min(20, Math.ceil(Math.sqrt(seconds.length))));
      const width = (hi - lo) / bins || 1;
      const counts = new Array(bins).fill(0);
      for (const s of seconds) counts[Math.min(bins - 1, Math.floor((s - lo) / width))]++;
      const centres = counts.map((_, i) => lo + (i + 0.5) * width);
      const box = el('div', {});
      root.append(section('Time per measurement', box));
      chart(box, `Distribution over ${seconds.length} runs (median ${fixed(study.median_seconds, 1)} s)`, centres,
        [{ label: 'runs', stroke: '#2ca02c', bars: true, values: counts }],
        { xLabel: 'seconds', yLabel: 'runs', height: 220, legend: false,
          xRange: [lo - 0.5 * width, lo + (bins + 0.5) * width], yRange: [0, Math.max(...counts) + 1] });
    }

    const cell = (r, d) => {
      const e = (r.error_mm || {})[d], u = (r.expanded_uncertainty_mm || {})[d];
      return el('td', { class: 'num' }, signed(e, 4) + (isNum(u) ? ` ± ${fixed(u, 4)}` : ''));
    };
    const runRows = runs.map((r) => el('tr', {}, el('td', {}, r.id),
      el('td', { class: 'num' }, fixed(r.seconds, 1)), dims.map((d) => cell(r, d))));
    root.append(el('details', {}, el('summary', {}, 'Every run: error ± U (mm)'),
      table(['Run', 'Seconds'].concat(dims), runRows)));
  }

  // Vertical bars error ± U and a zero line, drawn on the chart's canvas.
  function errorBars(u, errors, us) {
    const ctx = u.ctx;
    ctx.save();
    ctx.strokeStyle = '#1f77b4';
    ctx.lineWidth = 1.5 * devicePixelRatio;
    for (let i = 0; i < errors.length; i++) {
      if (!isNum(errors[i]) || !isNum(us[i])) continue;
      const x = u.valToPos(i + 1, 'x', true);
      const y0 = u.valToPos(errors[i] - us[i], 'y', true), y1 = u.valToPos(errors[i] + us[i], 'y', true);
      ctx.beginPath();
      ctx.moveTo(x, y0); ctx.lineTo(x, y1);
      ctx.moveTo(x - 3, y0); ctx.lineTo(x + 3, y0);
      ctx.moveTo(x - 3, y1); ctx.lineTo(x + 3, y1);
      ctx.stroke();
    }
    const z = u.valToPos(0, 'y', true);
    ctx.strokeStyle = '#999';
    ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(u.bbox.left, z); ctx.lineTo(u.bbox.left + u.bbox.width, z); ctx.stroke();
    ctx.restore();
  }

  // ---- main --------------------------------------------------------------

  const root = document.getElementById('report');
  try {
    const data = JSON.parse(document.getElementById('xgauge-data').textContent);
    const kind = document.documentElement.dataset.report;
    // Pages of other modules (spc.js) register in window.xgaugeExtraPages
    // and draw with these helpers.
    const pages = Object.assign({ measurement: measurementPage, calibration: calibrationPage, study: studyPage },
      window.xgaugeExtraPages || {});
    if (!pages[kind]) throw new Error('unknown report kind ' + kind);
    pages[kind](data, root, { el, svg, chart, table, section, meta, fixed, signed, general, isNum, palette });
    root.append(el('footer', {}, `Written by ${(data.result || data.calibration || data.failure || data.spc || {}).software || 'xgauge'} on ${data.generated || ''}. ` +
      'The JSON files beside this page hold every figure; charts by uPlot (MIT).'));
  } catch (e) {
    window.xgaugeErrors.push(String(e && e.stack ? e.stack : e));
    root.prepend(el('div', { class: 'error-box' }, 'This report could not be drawn completely: ' + String(e)));
  }
  document.documentElement.dataset.ready = 'true';
})();
