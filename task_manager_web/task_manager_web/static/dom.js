// Small helpers of the dashboard's modules: elements, the message line, how numbers and
// times are shown.

export const $ = (selector) => document.querySelector(selector);

export function element(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) {
    if (name === 'class') node.className = value;
    else if (name === 'text') node.textContent = value;
    else if (name.startsWith('on')) node.addEventListener(name.slice(2), value);
    else node.setAttribute(name, value);
  }
  for (const child of children) node.append(child);
  return node;
}

export function say(text, isError = false) {
  const message = $('#message');
  message.textContent = text;
  message.classList.toggle('error', isError);
}

export function formatSeconds(seconds) {
  if (seconds < 60) return `${seconds.toFixed(1)} s`;
  const minutes = Math.floor(seconds / 60);
  if (minutes < 60) return `${minutes} min ${Math.floor(seconds % 60)} s`;
  return `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
}

// A moment to come or past, from now: "in 4 min 10 s", "12.0 s ago".
export function fromNow(iso) {
  const seconds = (Date.parse(iso) - Date.now()) / 1000;
  return seconds >= 0 ? `in ${formatSeconds(seconds)}` : `${formatSeconds(-seconds)} ago`;
}

export function localTime(iso) {
  return iso ? new Date(iso).toLocaleString() : '';
}

// JSON with numbers to 3 decimals, cut at `limit` characters (the whole text is the title).
export function compactJson(value, limit = 160) {
  const text = JSON.stringify(value, (_, each) => (typeof each === 'number' && !Number.isInteger(each) ? Number(each.toFixed(3)) : each));
  return text.length > limit ? `${text.slice(0, limit - 1)}…` : text;
}

export function statusBadge(status) {
  return element('span', { class: `badge status-${status}`, text: status });
}
