// The video filters: object, part, pre-shape and outcome.
var videos = Array.prototype.slice.call(document.querySelectorAll('article.video'));
var pick = {};
['object', 'part', 'truth', 'outcome'].forEach(function (key) {
  pick[key] = document.getElementById('f-' + key);
  if (pick[key]) {
    pick[key].addEventListener('change', apply);
  }
});
// Filters preset from the address: report.html#outcome=vote-wrong&object=025_mug
// (other fragments, the sections' anchors, are left alone).
location.hash.replace(/^#/, '').split('&').forEach(function (pair) {
  var kv = pair.split('=');
  var key = decodeURIComponent(kv[0] || '');
  if (kv.length === 2 && pick.hasOwnProperty(key) && pick[key]) {
    pick[key].value = decodeURIComponent(kv[1]);
  }
});
function value(key) {
  return pick[key] ? pick[key].value : '';
}
function keeps(v) {
  var d = v.dataset;
  var voteWrong = Number(d.voteWrong);
  var handWrong = Number(d.handWrong);
  var outcome = value('outcome');
  return (!value('object') || d.object === value('object')) &&
    (!value('part') || d.part === value('part')) &&
    (!value('truth') || d.truth === value('truth')) &&
    (outcome === '' ||
      (outcome === 'vote-wrong' && voteWrong > 0) ||
      (outcome === 'vote-right' && voteWrong === 0) ||
      (outcome === 'hand-wrong' && handWrong > 0) ||
      (outcome === 'hand-right' && handWrong === 0));
}
function apply() {
  var shown = 0;
  videos.forEach(function (v) {
    var keep = keeps(v);
    v.hidden = !keep;
    shown += keep ? 1 : 0;
  });
  var count = document.getElementById('f-count');
  if (count) {
    count.textContent = shown + ' of ' + videos.length + ' videos shown';
  }
}
apply();
