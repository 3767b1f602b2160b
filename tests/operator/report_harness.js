// Evaluated by report_browser.py in the loaded report through the DevTools protocol (never part
// of the shipped page): measures the laid-out page and the dygraphs charts, zooms, hovers, and
// returns its findings.
(function () {
  function rect_box(r) { return {l: r.left, t: r.top + window.scrollY, r: r.right, b: r.bottom + window.scrollY}; }
  function box(e) { return rect_box(e.getBoundingClientRect()); }
  // The ink of a label, not its element: dygraphs' tick-label divs are wider than their text.
  function text_box(e) {
    var range = document.createRange();
    range.selectNodeContents(e);
    return rect_box(range.getBoundingClientRect());
  }
  // Half a pixel of slack: sub-pixel layout rounding is not an overlap.
  function inside(a, b) { return a.l >= b.l - 0.5 && a.r <= b.r + 0.5 && a.t >= b.t - 0.5 && a.b <= b.b + 0.5; }
  function meets(a, b) { return a.l < b.r - 0.5 && b.l < a.r - 0.5 && a.t < b.b - 0.5 && b.t < a.b - 0.5; }
  function visible(e) { var r = e.getBoundingClientRect(); return r.width > 0 && r.height > 0; }
  function pairwise(elements, what, problems, measure) {
    var boxes = elements.filter(visible).map(measure || box);
    for (var i = 0; i < boxes.length; ++i)
      for (var j = i + 1; j < boxes.length; ++j)
        if (meets(boxes[i], boxes[j])) problems.push(what + ' ' + i + ' and ' + j + ' overlap');
  }
  function all(root, selector) { return Array.prototype.slice.call(root.querySelectorAll(selector)); }

  function check_chart(fig, g, problems) {
    var id = fig.id, plot = fig.querySelector('.plot'), legend = fig.querySelector('.legend');
    var cap = fig.querySelector('figcaption'), fbox = box(fig), pbox = box(plot), lbox = box(legend);
    var series = g.getLabels().slice(1), finite = series.map(function () { return 0; });
    for (var r = 0; r < g.numRows(); ++r)
      for (var c = 1; c <= series.length; ++c) {
        var v = g.getValue(r, c);
        if (v !== null && isFinite(v)) finite[c - 1]++;
      }
    series.forEach(function (s, k) { if (finite[k] < 2) problems.push(id + ': series "' + s + '" has no data'); });
    var xt = all(plot, '.dygraph-axis-label-x'), yt = all(plot, '.dygraph-axis-label-y');
    if (xt.length < 2) problems.push(id + ': ' + xt.length + ' x tick labels');
    if (yt.length < 2) problems.push(id + ': ' + yt.length + ' y tick labels');
    var xl = plot.querySelector('.dygraph-xlabel'), yl = plot.querySelector('.dygraph-ylabel');
    if (!xl || !xl.textContent.trim()) problems.push(id + ': no x axis label');
    if (!yl || !yl.textContent.trim()) problems.push(id + ': no y axis label');
    pairwise(xt, id + ': x tick labels', problems, text_box);
    pairwise(yt, id + ': y tick labels', problems, text_box);
    if (yl) yt.forEach(function (t) { if (meets(text_box(yl), text_box(t))) problems.push(id + ': y label over ' + t.textContent); });
    if (xl) xt.forEach(function (t) { if (meets(text_box(xl), text_box(t))) problems.push(id + ': x label over ' + t.textContent); });
    if (!inside(lbox, fbox)) problems.push(id + ': legend outside its figure');
    if (meets(lbox, pbox)) problems.push(id + ': legend over the plot');
    if (meets(box(cap), pbox) || meets(box(cap), lbox)) problems.push(id + ': title over the plot or legend');
    if (!inside(pbox, fbox)) problems.push(id + ': plot outside its figure');
    all(plot, '.dygraph-axis-label, .dygraph-label').forEach(function (e) {
      if (visible(e) && !inside(text_box(e), fbox)) problems.push(id + ': axis text outside the figure: ' + e.textContent);
    });
    series.forEach(function (s) {
      if (legend.textContent.indexOf(s) < 0) problems.push(id + ': legend lacks "' + s + '"');
    });
    return {id: id, rows: g.numRows(), series: series.length, x_ticks: xt.length, y_ticks: yt.length};
  }

  function check_zoom(graphs, problems) {
    var g = graphs[0], full = g.xAxisRange(), span = full[1] - full[0];
    // Hover: selecting a row puts its values into the legend.
    g.setSelection(Math.floor(g.numRows() / 2));
    var legend = document.getElementById('legend-' + g.maindiv_.id.replace('plot-', ''));
    if (!/\d/.test(legend.textContent)) problems.push('hover: no values in the legend');
    g.clearSelection();
    var want = [full[0] + 0.4 * span, full[0] + 0.45 * span];
    g.updateOptions({dateWindow: want});
    var got = g.xAxisRange(), other = graphs[graphs.length - 1].xAxisRange();
    var close = function (a, b) { return Math.abs(a[0] - b[0]) < 1e-6 * span && Math.abs(a[1] - b[1]) < 1e-6 * span; };
    if (!close(got, want)) problems.push('zoom: window ' + got + ' instead of ' + want);
    if (!close(other, want)) problems.push('zoom: the last chart did not follow (' + other + ')');
    all(document, 'figure.chart .plot').forEach(function (plot) {
      pairwise(all(plot, '.dygraph-axis-label-x'), plot.id + ' zoomed: x tick labels', problems, text_box);
    });
    g.resetZoom();
    var back = g.xAxisRange();
    if (!close(back, full)) problems.push('zoom: reset gives ' + back);
    return {full: full, zoomed: got, follower: other};
  }

  var problems = [], graphs = window.maglead ? window.maglead.graphs : [];
  var figs = all(document, 'figure.chart');
  if (!graphs.length || graphs.length !== figs.length) problems.push(figs.length + ' charts, ' + graphs.length + ' graphs');
  var charts = figs.map(function (f, i) { return graphs[i] ? check_chart(f, graphs[i], problems) : null; });
  all(document, 'img').forEach(function (im) {
    if (!im.complete || im.naturalWidth === 0) problems.push('image ' + im.alt + ' does not decode');
    if (!inside(box(im), box(im.closest('figure')))) problems.push('image ' + im.alt + ' outside its figure');
  });
  var blocks = all(document, 'body > h1, body > h2, body > p, body > table, body > figure');
  pairwise(blocks, 'page blocks', problems);
  blocks.forEach(function (b) {
    if (box(b).r > window.innerWidth + 0.5) problems.push(b.tagName + (b.id ? '#' + b.id : '') + ' wider than the window');
  });
  if (document.documentElement.scrollWidth > window.innerWidth) problems.push('the page scrolls sideways');
  var zoom = graphs.length ? check_zoom(graphs, problems) : null;
  return {viewport: [window.innerWidth, window.innerHeight], charts: charts, zoom: zoom, problems: problems};
})()
