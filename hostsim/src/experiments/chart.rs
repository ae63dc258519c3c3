//! The experiments' line charts: each series a line with a dot at every point, named in a
//! legend, on whatever axes (linear or logarithmic) the chart was built with, or on linear
//! axes from zero ([`linear`]).

use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// One series: its points, colour and legend label.
#[derive(Clone, Debug)]
pub struct Line {
    /// (x, y) in the chart's units.
    pub points: Vec<(f64, f64)>,
    /// Line, dots and legend mark.
    pub colour: RGBColor,
    /// The legend's words.
    pub label: String,
}

/// A chart on `area` titled `caption`, its axes linear from 0 to a tenth past `max` (x, y)
/// and labelled `desc` (x, y), its mesh drawn.
pub fn linear<'a, DB: DrawingBackend + 'a>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    desc: (&str, &str),
    max: (f64, f64),
) -> Result<ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>, String> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(0f64..max.0 * 1.1, 0f64..max.1 * 1.1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(desc.0)
        .y_desc(desc.1)
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(chart)
}

/// Draw `lines` on `chart`, then the legend at the middle of its right side.
pub fn draw<'a, DB, X>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, RangedCoordf64>>,
    lines: Vec<Line>,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
{
    draw_at(chart, lines, SeriesLabelPosition::MiddleRight)
}

/// Draw `lines` on `chart`, then the legend at `legend`: where the lines leave room.
pub fn draw_at<'a, DB, X>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, RangedCoordf64>>,
    lines: Vec<Line>,
    legend: SeriesLabelPosition,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
{
    for Line {
        points,
        colour,
        label,
    } in lines
    {
        chart
            .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], colour));
        chart
            .draw_series(
                points
                    .into_iter()
                    .map(|p| Circle::new(p, 3, colour.filled())),
            )
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .position(legend)
        .border_style(BLACK)
        .background_style(WHITE)
        .draw()
        .map_err(|e| e.to_string())
}
