//! A [`Display`] as a Yamcs Studio display (`.opi`, the BOY XML format Yamcs web draws):
//! each section a framed box with its title, column headings and rows; a value a Text
//! Update (calibrated numbers with the description's decimals and their unit, alarm
//! colours on), a lamp an LED. Every widget carries the full property set Yamcs web's
//! renderer reads (it refuses a widget that lacks one).

use super::{Cell, Display, Lit, ParameterKind, Section};
use crate::mdb::Mdb;

/// An RGB colour.
#[derive(Clone, Copy)]
struct Rgb(u8, u8, u8);

const BACKGROUND: Rgb = Rgb(250, 250, 250);
const BOX_FILL: Rgb = Rgb(255, 255, 255);
const BOX_LINE: Rgb = Rgb(176, 188, 204);
const TITLE: Rgb = Rgb(28, 58, 92);
const HEADING: Rgb = Rgb(110, 110, 110);
const LABEL: Rgb = Rgb(48, 48, 48);
const VALUE_FILL: Rgb = Rgb(236, 240, 245);
const VALUE_TEXT: Rgb = Rgb(0, 0, 0);
const LAMP_OFF: Rgb = Rgb(205, 205, 205);

fn lit_colour(lit: Lit) -> Rgb {
    match lit {
        Lit::Good => Rgb(0, 170, 0),
        Lit::Activity => Rgb(30, 110, 230),
        Lit::Attention => Rgb(240, 160, 0),
        Lit::Bad => Rgb(220, 0, 0),
    }
}

/// Layout (pixels).
const MARGIN: i32 = 10;
const GAP: i32 = 14;
const TITLE_H: i32 = 26;
const SECTION_TITLE_H: i32 = 24;
const HEADING_H: i32 = 18;
const ROW_H: i32 = 22;
const PAD: i32 = 8;
/// A value column of a section with several columns.
const VALUE_W: i32 = 130;
/// The value column of a section with one column (room for long enumeration labels).
const WIDE_VALUE_W: i32 = 220;
const LAMP_W: i32 = 74;
const LAMP_SIZE: i32 = 16;
/// Width of a label character at the label font (pixels, generous).
const CHAR_W: i32 = 7;
const MIN_LABEL_W: i32 = 40;

fn colour(name: &str, c: Rgb) -> String {
    format!(
        "<{name}><color red=\"{}\" green=\"{}\" blue=\"{}\" /></{name}>",
        c.0, c.1, c.2
    )
}

fn font(size: u32, bold: bool) -> String {
    format!(
        "<font><opifont.name fontName=\"Arial\" height=\"{size}\" style=\"{}\">Default</opifont.name></font>",
        u8::from(bold)
    )
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The properties every widget has.
fn common(kind: &str, wuid: usize, x: i32, y: i32, w: i32, h: i32) -> String {
    format!(
        "<widget_type>{kind}</widget_type><name>{kind} {wuid}</name><wuid>m2-{wuid}</wuid>\
         <x>{x}</x><y>{y}</y><width>{w}</width><height>{h}</height>\
         <visible>true</visible><enabled>true</enabled><rules /><scripts />\
         <actions hook=\"false\" hook_all=\"false\" />\
         <scale_options><width_scalable>true</width_scalable><height_scalable>true</height_scalable>\
         <keep_wh_ratio>false</keep_wh_ratio></scale_options>\
         <border_style>0</border_style><border_width>1</border_width>{}",
        colour("border_color", BOX_LINE)
    )
}

/// Writes widgets with consecutive IDs.
struct Writer {
    out: String,
    next: usize,
}

impl Writer {
    fn id(&mut self) -> usize {
        self.next += 1;
        self.next
    }

    fn widget(&mut self, type_id: &str, body: String) {
        self.out.push_str(&format!(
            "  <widget typeId=\"org.csstudio.opibuilder.widgets.{type_id}\" version=\"1.0.0\">{body}</widget>\n"
        ));
    }

    #[allow(clippy::too_many_arguments)]
    fn label(
        &mut self,
        x: i32,
        y: i32,
        w: i32,
        h: i32,
        text: &str,
        size: u32,
        bold: bool,
        fg: Rgb,
        align: u8,
    ) {
        let id = self.id();
        let body = format!(
            "{}<text>{}</text><tooltip></tooltip><transparent>true</transparent>\
             <auto_size>false</auto_size><wrap_words>false</wrap_words>\
             <horizontal_alignment>{align}</horizontal_alignment><vertical_alignment>1</vertical_alignment>\
             {}{}{}",
            common("Label", id, x, y, w, h),
            escape(text),
            colour("background_color", BOX_FILL),
            colour("foreground_color", fg),
            font(size, bold)
        );
        self.widget("Label", body);
    }

    fn rectangle(&mut self, x: i32, y: i32, w: i32, h: i32) {
        let id = self.id();
        let body = format!(
            "{}<pv_name></pv_name><pv_value /><tooltip></tooltip><transparent>false</transparent>\
             <alpha>255</alpha><line_width>1</line_width><line_style>0</line_style>\
             <horizontal_fill>true</horizontal_fill><fill_level>0.0</fill_level>\
             <gradient>false</gradient><anti_alias>true</anti_alias>\
             <alarm_pulsing>false</alarm_pulsing><border_alarm_sensitive>false</border_alarm_sensitive>\
             <forecolor_alarm_sensitive>false</forecolor_alarm_sensitive>\
             <backcolor_alarm_sensitive>false</backcolor_alarm_sensitive>\
             {}{}{}{}{}{}",
            common("Rectangle", id, x, y, w, h),
            colour("background_color", BOX_FILL),
            colour("foreground_color", BOX_FILL),
            colour("line_color", BOX_LINE),
            colour("bg_gradient_color", BOX_FILL),
            colour("fg_gradient_color", BOX_FILL),
            font(10, false)
        );
        self.widget("Rectangle", body);
    }

    /// A parameter's value: calibrated numbers with `decimals` and their unit.
    fn text_update(&mut self, x: i32, y: i32, w: i32, h: i32, pv: &str, decimals: Option<u32>) {
        let id = self.id();
        let (format_type, precision, from_pv) = match decimals {
            Some(d) => (1, d, false),
            None => (0, 0, true),
        };
        let body = format!(
            "{}<pv_name>{}</pv_name><pv_value /><tooltip>$(pv_name)\n$(pv_value)</tooltip>\
             <text></text><transparent>false</transparent><auto_size>false</auto_size>\
             <wrap_words>false</wrap_words><rotation_angle>0.0</rotation_angle>\
             <horizontal_alignment>2</horizontal_alignment><vertical_alignment>1</vertical_alignment>\
             <format_type>{format_type}</format_type><precision>{precision}</precision>\
             <precision_from_pv>{from_pv}</precision_from_pv><show_units>true</show_units>\
             <alarm_pulsing>false</alarm_pulsing><border_alarm_sensitive>true</border_alarm_sensitive>\
             <forecolor_alarm_sensitive>true</forecolor_alarm_sensitive>\
             <backcolor_alarm_sensitive>false</backcolor_alarm_sensitive>\
             {}{}{}",
            common("Text Update", id, x, y, w, h),
            escape(pv),
            colour("background_color", VALUE_FILL),
            colour("foreground_color", VALUE_TEXT),
            font(10, false)
        );
        self.widget("TextUpdate", body);
    }

    fn led(&mut self, x: i32, y: i32, size: i32, pv: &str, lit: Lit) {
        let id = self.id();
        let body = format!(
            "{}<pv_name>{}</pv_name><pv_value /><tooltip>$(pv_name)\n$(pv_value)</tooltip>\
             <bit>-1</bit><data_type>0</data_type><effect_3d>false</effect_3d>\
             <square_led>false</square_led><show_boolean_label>false</show_boolean_label>\
             <on_label>ON</on_label><off_label>OFF</off_label>\
             <alarm_pulsing>false</alarm_pulsing><border_alarm_sensitive>false</border_alarm_sensitive>\
             <forecolor_alarm_sensitive>false</forecolor_alarm_sensitive>\
             <backcolor_alarm_sensitive>false</backcolor_alarm_sensitive>\
             {}{}{}{}{}",
            common("LED", id, x, y, size, size),
            escape(pv),
            colour("on_color", lit_colour(lit)),
            colour("off_color", LAMP_OFF),
            colour("background_color", BOX_FILL),
            colour("foreground_color", LABEL),
            font(10, false)
        );
        self.widget("LED", body);
    }
}

/// Column widths of a section: the label column, then one per column.
fn widths(s: &Section) -> (i32, Vec<i32>) {
    let longest = s
        .rows
        .iter()
        .map(|r| r.label.chars().count())
        .max()
        .unwrap_or(0);
    let label_w = (i32::try_from(longest).unwrap_or(0) * CHAR_W + PAD * 2).max(MIN_LABEL_W);
    let value_w = if s.columns.len() == 1 {
        WIDE_VALUE_W
    } else {
        VALUE_W
    };
    let cols = (0..s.columns.len())
        .map(|c| {
            let lamp = s
                .rows
                .iter()
                .any(|r| matches!(r.cells.get(c), Some(Some(Cell::Lamp { .. }))));
            let value = s
                .rows
                .iter()
                .any(|r| matches!(r.cells.get(c), Some(Some(Cell::Value(_)))));
            if value || !lamp {
                value_w
            } else {
                LAMP_W
            }
        })
        .collect();
    (label_w, cols)
}

fn section_size(s: &Section) -> (i32, i32) {
    let (label_w, cols) = widths(s);
    let headings = if s.columns.iter().any(|c| !c.is_empty()) {
        HEADING_H
    } else {
        0
    };
    let rows = i32::try_from(s.rows.len()).unwrap_or(0);
    (
        label_w + cols.iter().sum::<i32>() + PAD * 2,
        SECTION_TITLE_H + headings + rows * ROW_H + PAD,
    )
}

/// The `.opi` file of `display`; `kind` gives a parameter's kind (its decimals).
pub(super) fn display_opi(
    mdb: &Mdb,
    display: &Display,
    kind: &dyn Fn(&str) -> Option<ParameterKind>,
) -> String {
    let mut w = Writer {
        out: String::new(),
        next: 0,
    };
    let placements = display
        .sections
        .iter()
        .map(|s| s.placement)
        .max()
        .map_or(0, |m| m + 1);
    let mut col_x = Vec::new();
    let mut x = MARGIN;
    for p in 0..placements {
        col_x.push(x);
        let width = display
            .sections
            .iter()
            .filter(|s| s.placement == p)
            .map(|s| section_size(s).0)
            .max()
            .unwrap_or(0);
        x += width + GAP;
    }
    let total_w = x - GAP + MARGIN;
    let mut col_y = vec![MARGIN + TITLE_H + PAD; placements];
    w.label(
        MARGIN,
        MARGIN,
        total_w - 2 * MARGIN,
        TITLE_H,
        display.title,
        14,
        true,
        TITLE,
        0,
    );
    for s in &display.sections {
        let (sw, sh) = section_size(s);
        let x0 = col_x.get(s.placement).copied().unwrap_or(MARGIN);
        let y0 = col_y.get(s.placement).copied().unwrap_or(MARGIN);
        w.rectangle(x0, y0, sw, sh);
        w.label(
            x0 + PAD,
            y0 + 2,
            sw - 2 * PAD,
            SECTION_TITLE_H - 2,
            s.title,
            11,
            true,
            TITLE,
            0,
        );
        let (label_w, cols) = widths(s);
        let mut y = y0 + SECTION_TITLE_H;
        if s.columns.iter().any(|c| !c.is_empty()) {
            let mut cx = x0 + PAD + label_w;
            for (c, cw) in s.columns.iter().zip(&cols) {
                w.label(cx, y, *cw, HEADING_H, c, 9, false, HEADING, 1);
                cx += cw;
            }
            y += HEADING_H;
        }
        for row in &s.rows {
            w.label(
                x0 + PAD,
                y,
                label_w,
                ROW_H - 2,
                &row.label,
                10,
                false,
                LABEL,
                0,
            );
            let mut cx = x0 + PAD + label_w;
            for (cell, cw) in row.cells.iter().zip(&cols) {
                match cell {
                    Some(Cell::Value(p)) => {
                        let decimals = match kind(p) {
                            Some(ParameterKind::Float {
                                fraction_digits, ..
                            }) => fraction_digits,
                            _ => None,
                        };
                        w.text_update(
                            cx + 2,
                            y + 1,
                            cw - 4,
                            ROW_H - 4,
                            &mdb.qualified(p),
                            decimals,
                        );
                    }
                    Some(Cell::Lamp { parameter, lit }) => {
                        w.led(
                            cx + (cw - LAMP_SIZE) / 2,
                            y + (ROW_H - LAMP_SIZE) / 2,
                            LAMP_SIZE,
                            &mdb.qualified(parameter),
                            *lit,
                        );
                    }
                    None => {}
                }
                cx += cw;
            }
            y += ROW_H;
        }
        if let Some(cy) = col_y.get_mut(s.placement) {
            *cy = y0 + sh + GAP;
        }
    }
    let total_h = col_y.iter().copied().max().unwrap_or(0) - GAP + MARGIN;
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <display typeId=\"org.csstudio.opibuilder.Display\" version=\"1.0.0\">\n  \
         <!-- Generated from the mission database by ground/src/mdb/console.rs; the test \
         ground/tests/console.rs rewrites it with M2_WRITE_CONSOLE=1. -->\n  \
         <widget_type>Display</widget_type><name>{}</name><wuid>m2-display</wuid>\
         <x>0</x><y>0</y><width>{total_w}</width><height>{total_h}</height>\
         <show_grid>false</show_grid><grid_space>6</grid_space><show_ruler>false</show_ruler>\
         <snap_to_geometry>false</snap_to_geometry><show_edit_range>true</show_edit_range>\
         <show_close_button>true</show_close_button><auto_zoom_to_fit_all>false</auto_zoom_to_fit_all>\
         <rules /><scripts /><macros><include_parent_macros>true</include_parent_macros></macros>\
         <actions hook=\"false\" hook_all=\"false\" /><boy_version>4.0.104</boy_version>\
         <auto_scale_widgets><auto_scale_widgets>false</auto_scale_widgets><min_width>-1</min_width>\
         <min_height>-1</min_height></auto_scale_widgets>{}{}\n{}</display>\n",
        escape(display.title),
        colour("background_color", BACKGROUND),
        colour("foreground_color", LABEL),
        w.out
    )
}
