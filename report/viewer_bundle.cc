// The viewer bundle (report/viewer/viewer.js built by esbuild at build time) as the
// symbols hw_report_viewer_bundle … hw_report_viewer_bundle_end, linked in with the
// assembler's .incbin: no hex conversion, and the build only re-assembles this file when
// the bundle changes (OBJECT_DEPENDS in report/CMakeLists.txt). ccache does not cache
// sources with .incbin, so a stale bundle is never reused.

#ifndef HW_VIEWER_BUNDLE_PATH
#error "HW_VIEWER_BUNDLE_PATH must name the built viewer bundle (report/CMakeLists.txt)"
#endif

asm(".section .rodata\n"
    ".global hw_report_viewer_bundle\n"
    ".global hw_report_viewer_bundle_end\n"
    ".balign 16\n"
    "hw_report_viewer_bundle:\n"
    ".incbin \"" HW_VIEWER_BUNDLE_PATH "\"\n"
    "hw_report_viewer_bundle_end:\n"
    ".byte 0\n"
    ".previous\n");
