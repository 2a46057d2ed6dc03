use super::*;

fn msg(text: &str) -> Result<MessageSpec, ParseError> {
    parse_message("pkg", "Thing", "pkg/msg/Thing.msg", text)
}

fn err(text: &str) -> String {
    msg(text).expect_err("should not parse").to_string()
}

#[test]
fn parses_all_type_forms() {
    let m = msg("# head doc\n\n\
        bool a\nbyte b\nchar c\nint8 d -3\nuint64 e 0x10\nfloat32 f 1.5\nstring g \"hi # not a comment\"\n\
        string<=5 h\nfloat64[] i\nint32[3] j [1, -2, 3]\nuint8[<=4] k\nstring<=3[<=2] l\n\
        Header header\ngeometry_msgs/Pose pose\nOther o  # trailing doc\n\
        int8 NEG=-1\nstring NAME = \"x#y\"\n")
    .unwrap();
    assert_eq!(m.doc, vec!["head doc".to_string()]);
    assert_eq!(m.fields.len(), 15);
    assert_eq!(m.fields[3].default, Some(Value::Int(-3)));
    assert_eq!(m.fields[4].default, Some(Value::Int(16)));
    assert_eq!(
        m.fields[6].default,
        Some(Value::Str("hi # not a comment".into()))
    );
    assert_eq!(m.fields[7].ty.base, BaseType::String { bound: Some(5) });
    assert_eq!(m.fields[9].ty.array, ArrayKind::Fixed(3));
    assert_eq!(
        m.fields[9].default,
        Some(Value::Array(vec![
            Value::Int(1),
            Value::Int(-2),
            Value::Int(3)
        ]))
    );
    assert_eq!(m.fields[10].ty.array, ArrayKind::Bounded(4));
    assert_eq!(
        m.fields[11].ty,
        FieldType {
            base: BaseType::String { bound: Some(3) },
            array: ArrayKind::Bounded(2)
        }
    );
    assert_eq!(
        m.fields[12].ty.base,
        BaseType::Named {
            package: "std_msgs".into(),
            name: "Header".into()
        }
    );
    assert_eq!(
        m.fields[13].ty.base,
        BaseType::Named {
            package: "geometry_msgs".into(),
            name: "Pose".into()
        }
    );
    assert_eq!(
        m.fields[14].ty.base,
        BaseType::Named {
            package: "pkg".into(),
            name: "Other".into()
        }
    );
    assert_eq!(m.fields[14].doc, vec!["trailing doc".to_string()]);
    assert_eq!(m.constants[0].value, Value::Int(-1));
    assert_eq!(m.constants[1].value, Value::Str("x#y".into()));
}

#[test]
fn errors_name_file_and_line() {
    assert_eq!(
        err("int32 a\nfloat65 b\n"),
        "pkg/msg/Thing.msg:2: unknown type `float65`: expected a primitive (bool, byte, char, int8..uint64, float32, \
         float64, string), `package/Type` or a same-package `Type`"
    );
    assert!(err("int32\n").starts_with("pkg/msg/Thing.msg:1: `int32` has no name"));
    assert!(
        err("\n\nint32 BadName\n")
            .starts_with("pkg/msg/Thing.msg:3: field name `BadName` must be snake_case")
    );
    assert!(
        err("int8 a 300\n").contains(":1: default of field a: 300 is out of range [-128, 127]")
    );
    assert!(err("uint8 X=-1\n").contains(":1: constant X: -1 is out of range"));
    assert!(err("int32[2] a [1, 2, 3]\n").contains("3 elements given, the array has exactly 2"));
    assert!(err("int32[x] a\n").contains("array size `x` is not a non-negative integer"));
    assert!(err("int32[3 a\n").contains("malformed array type"));
    assert!(err("int32 a\nint32 a\n").contains(":2: field a is declared twice"));
    assert!(err("bool a maybe\n").contains("is not a bool"));
    assert!(err("int32[] X=1\n").contains("constants must be primitive scalars"));
    assert!(err("wstring w\n").contains("`wstring` is not supported"));
    assert!(err("string s \"open\n").contains("unterminated string literal"));
    assert!(err("geometry_msgs/pose p\n").contains("must be CamelCase"));
    assert!(err("int32<=3 a\n").contains("only `string` and `wstring` can be bounded"));
}

#[test]
fn service_split() {
    let s = parse_service("pkg", "Do", "Do.srv", "# svc doc\nint32 a\n---\nbool ok\n").unwrap();
    assert_eq!(s.request.name, "Do_Request");
    assert_eq!(s.response.name, "Do_Response");
    assert_eq!(s.request.text, "# svc doc\nint32 a\n");
    assert_eq!(s.response.text, "bool ok\n");
    let e = parse_service("pkg", "Do", "Do.srv", "int32 a\n").unwrap_err();
    assert_eq!(
        e.to_string(),
        "Do.srv:0: service has no `---` line separating request and response"
    );
    let e = parse_service("pkg", "Do", "Do.srv", "int32 a\n---\n---\n").unwrap_err();
    assert!(e.to_string().starts_with("Do.srv:3: second `---`"));
    let e = parse_service("pkg", "Do", "Do.srv", "int32 a\n---\nbool Ok\n").unwrap_err();
    assert!(
        e.to_string().starts_with("Do.srv:3: field name `Ok`"),
        "{e}"
    );
}

#[test]
fn unknown_reference_is_reported() {
    let i = vec![Interface::Message {
        file: "A.msg".into(),
        spec: parse_message("p", "A", "A.msg", "\nB b\n").unwrap(),
    }];
    let e = generate("p", &i).unwrap_err().to_string();
    assert!(
        e.starts_with("A.msg:2: field b: unknown message type `p/B`"),
        "{e}"
    );
}

#[test]
fn recursion_is_rejected() {
    let i = vec![
        Interface::Message {
            file: "A.msg".into(),
            spec: parse_message("p", "A", "A.msg", "B b\n").unwrap(),
        },
        Interface::Message {
            file: "B.msg".into(),
            spec: parse_message("p", "B", "B.msg", "A[] a\n").unwrap(),
        },
    ];
    let e = generate("p", &i).unwrap_err().to_string();
    assert!(
        e.contains("recursive message definition: p/A -> p/B -> p/A"),
        "{e}"
    );
}
