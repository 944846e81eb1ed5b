// Any uncaught error marks the page: a headless browser's DOM then says so.
window.onerror = function (message, source, line) {
  var box = document.getElementById('script-error');
  if (!box) {
    box = document.createElement('pre');
    box.id = 'script-error';
    (document.body || document.documentElement).appendChild(box);
  }
  box.textContent += 'script error: ' + message + ' (line ' + line + ')\n';
};
