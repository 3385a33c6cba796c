/* view_page.h - the viewer page: src/view/viewer.html (HTML, JS and GLSL in one file, nothing
 * loaded from the network), compiled in as bytes by cmake/embed.cmake. It reads scene.pgvs from
 * its own directory; docs/viewer.md lists its controls and URL options. */
#ifndef PG_VIEW_PAGE_H
#define PG_VIEW_PAGE_H

#include <stddef.h>

extern const unsigned char view_page_html[]; /* NUL-terminated */
extern const size_t view_page_html_size;     /* without the NUL */

#endif
