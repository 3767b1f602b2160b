#pragma once
// Text for HTML pages: escaping, base64 for embedded images, numbers for people.
#include <string>
#include <string_view>

namespace maglead::report {

/// Escapes &, <, > and " so text is safe in element content and quoted attributes.
std::string escape_html(std::string_view text);

/// RFC 4648 base64 (with padding), for data: URLs.
std::string base64(std::string_view bytes);

/// PNG bytes as a data:image/png URL: a page's figures live in the page, no file beside it.
std::string data_url_of_png_bytes(const std::string& png_bytes);

/// `significant` digits, "–" for NaN or infinity, a real minus sign.
std::string number(double value, int significant = 3);
/// A figure at a fixed number of decimals (gains in %, t statistics), "−" for minus, no sign on
/// a zero: a figure that is zero at the shown resolution reads 0.00, never 1.81e-08.
std::string fixed(double value, int decimals);

}  // namespace maglead::report
