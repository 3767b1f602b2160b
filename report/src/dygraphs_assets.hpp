#pragma once
// libjs-dygraphs' files, compiled in at build time (generated dygraphs_assets.cpp).
namespace maglead::report::assets {
extern const char* const dygraph_min_js;
extern const char* const dygraph_min_css;
extern const char* const extras_synchronizer_js;
}  // namespace maglead::report::assets
