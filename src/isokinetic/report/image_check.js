// Counts, after `load`, the figures that decoded; the browser test and CI read the attributes.
window.addEventListener("load", function () {
  var imgs = document.images, ok = 0, broken = [];
  for (var i = 0; i < imgs.length; i++) {
    if (imgs[i].complete && imgs[i].naturalWidth > 0) { ok++; }
    else { broken.push(imgs[i].getAttribute("data-file") || imgs[i].alt || String(i)); }
  }
  document.body.setAttribute("data-images-loaded", String(ok));
  document.body.setAttribute("data-images-total", String(imgs.length));
  document.body.setAttribute("data-images-broken", broken.join(" "));
});
