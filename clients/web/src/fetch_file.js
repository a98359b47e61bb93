// Fetches one file of a bake with an error that names it: a missing file, a server error and
// a page opened from file:// without file access (Chromium blocks such fetches) read differently.
export async function fetchFile(url, as = 'arrayBuffer') {
  let response;
  try {
    response = await fetch(url);
  } catch (e) {
    const hint = url.startsWith('file:')
      ? ' (a page opened from file:// may not read files: serve the folder over HTTP or start Chromium with --allow-file-access-from-files, docs/web.md)'
      : '';
    throw new Error(`cannot fetch ${url}: ${e.message}${hint}`);
  }
  if (!response.ok) throw new Error(`cannot fetch ${url}: HTTP ${response.status}`);
  return as === 'json' ? response.json().catch((e) => { throw new Error(`${url} is not JSON: ${e.message}`); }) : response.arrayBuffer();
}
