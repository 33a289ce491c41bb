#include "report/report_writer.h"

#include <cassert>
#include <chrono>

#include "analyze/thermal_mesh.h"
#include "core/atomic_file.h"
#include "core/output_folder.h"

namespace hw::report {

std::string ReportWriteOptions::Check() const {
  if (!html && !pdf) return "html, pdf (--no-html, --no-pdf): at least one of report.html and report.pdf must be written";
  if (const std::string p = pdf_options.Check(); !p.empty()) return "pdf." + p;
  if (const std::string p = viewer.Check(); !p.empty()) return "viewer." + p;
  return "";
}

ReportWriteResult WriteReport(const ReportInputs& inputs, const std::filesystem::path& out_folder,
                              const ReportWriteOptions& options,
                              const std::function<void(int done, int total)>& progress) {
  assert(options.Check().empty());
  const auto start = std::chrono::steady_clock::now();
  const bool model_view = options.html && options.model_view && !inputs.model_ply.empty();
  const int total = 1 + (model_view ? 1 : 0) + (options.html ? 1 : 0) + (options.pdf ? 1 : 0);
  int done = 0;
  auto step = [&] {
    if (progress) progress(++done, total);
  };
  Document doc = BuildDocument(inputs);
  step();
  if (!model_view) doc.model_view.reset();
  HtmlOptions html_options;
  ReportWriteResult result;
  if (model_view && doc.model_view) {
    const analyze::ThermalMesh mesh = analyze::ReadThermalMesh(inputs.model_ply);
    html_options.model_view_html = ViewerHtml(mesh, *doc.model_view, options.viewer, &result.viewer);
    html_options.content_security_policy = ViewerContentSecurityPolicy();
    step();
  }
  // The HTML is rendered in memory first: it decodes every figure, so a bad image fails
  // here, before the folder is touched.
  std::string html;
  if (options.html) html = RenderHtml(doc, html_options, &result.html.images);

  core::OutputFolder folder(out_folder, "heatwave report");
  if (options.html) {
    result.html_path = out_folder / "report.html";
    const auto t0 = std::chrono::steady_clock::now();
    core::WriteFileAtomically(result.html_path, html);
    result.html.bytes = static_cast<int64_t>(html.size());
    result.html.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    step();
  }
  if (options.pdf) {
    result.pdf_path = out_folder / "report.pdf";
    result.pdf = WritePdf(doc, result.pdf_path, options.pdf_options);
    step();
  }
  folder.Commit();
  for (const auto& row : doc.cover.summary.rows) {
    if (row.size() < 4 || row[0] == "Total") continue;
    const int n = std::stoi(row[2]) + std::stoi(row[3]);
    result.spots_by_severity.emplace_back(row[0], n);
    result.spots += n;
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hw::report
