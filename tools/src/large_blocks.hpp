#pragma once
// The maglead command's operator new (large_blocks.cpp) advises blocks of 4 MiB or more to
// transparent huge pages once a command that reads whole recordings turns it on. The controller's
// commands (serve, record) never do: a huge page's first touch may wait on the kernel compacting
// memory, which an offline analysis can afford and a 1 kHz loop's process should not risk.
namespace maglead::cli {

/// From now on, large blocks are advised to huge pages (only the speed differs, never a value).
void advise_large_blocks_to_huge_pages();
/// False in sanitized builds, which keep the sanitizer's operator new (no advice at all).
bool huge_page_advice_built();

}  // namespace maglead::cli
