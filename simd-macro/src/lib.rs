//! The attribute behind `afe_core::simd_kernel!`: it compiles a kernel once per
//! instruction set (with `multiversion`) and once more as an AVX2 set of its own, which
//! `afe_core::cpu::avx512_switched_off` (`AFE_NO_AVX512=1`) makes an AVX-512 CPU take: the
//! AVX2 path measured and tested on a host that has AVX-512, without a second build.

use proc_macro2::TokenStream;
use quote::{format_ident, quote};
use syn::{parse_macro_input, FnArg, GenericParam, ItemFn, Meta};

/// Wraps a free function `f` into `f` itself, which calls `__f_clones` (multiversion's
/// AVX-512 + AVX2 clones, AVX2 alone under the calling crate's `no-avx512` feature) or,
/// where the switch holds, `__f_avx2` (AVX2 alone). `#[kernel(fma)]` adds FMA to the AVX2
/// clones. The calling crate depends on `multiversion` and `afe-core`.
#[proc_macro_attribute]
pub fn kernel(
    attr: proc_macro::TokenStream,
    item: proc_macro::TokenStream,
) -> proc_macro::TokenStream {
    let func = parse_macro_input!(item as ItemFn);
    let fma = match attr.to_string().as_str() {
        "" => false,
        "fma" => true,
        other => {
            let message = format!("`kernel` takes `fma` or nothing, not `{other}`");
            return quote!(compile_error!(#message);).into();
        }
    };
    clones(func, fma)
        .unwrap_or_else(|e| e.to_compile_error())
        .into()
}

fn clones(func: ItemFn, fma: bool) -> syn::Result<TokenStream> {
    let narrow = if fma {
        "x86_64+avx2+fma"
    } else {
        "x86_64+avx2"
    };
    let wide = "x86_64+avx512f+avx512vl";
    let ItemFn {
        attrs,
        vis,
        sig,
        block,
    } = func;
    // documentation on the function callers see; lint levels on every clone too
    let (docs, others): (Vec<_>, Vec<_>) = attrs
        .into_iter()
        .partition(|a| matches!(&a.meta, Meta::NameValue(nv) if nv.path.is_ident("doc")));
    let name = &sig.ident;
    let (all, avx2) = (
        format_ident!("__{}_clones", name),
        format_ident!("__{}_avx2", name),
    );
    let mut outer = sig.clone();
    let mut args = Vec::new();
    for (i, input) in outer.inputs.iter_mut().enumerate() {
        match input {
            FnArg::Typed(typed) => {
                let arg = format_ident!("__arg{}", i);
                *typed.pat = syn::parse_quote!(#arg);
                args.push(arg);
            }
            FnArg::Receiver(r) => {
                return Err(syn::Error::new_spanned(r, "a kernel is a free function"));
            }
        }
    }
    if quote!(#outer).to_string().contains("impl ") {
        return Err(syn::Error::new_spanned(
            &outer,
            "a kernel's argument types name their generics (no `impl Trait`)",
        ));
    }
    let params: Vec<_> = sig
        .generics
        .params
        .iter()
        .filter_map(|p| match p {
            GenericParam::Type(t) => Some(t.ident.clone()),
            GenericParam::Const(c) => Some(c.ident.clone()),
            GenericParam::Lifetime(_) => None,
        })
        .collect();
    let turbofish = if params.is_empty() {
        quote!()
    } else {
        quote!(::<#(#params),*>)
    };
    let (mut all_sig, mut avx2_sig) = (sig.clone(), sig);
    all_sig.ident = all.clone();
    avx2_sig.ident = avx2.clone();
    Ok(quote! {
        #(#docs)*
        #(#others)*
        #[inline]
        #vis #outer {
            #[cfg(not(feature = "no-avx512"))]
            if ::afe_core::cpu::avx512_switched_off() {
                return #avx2 #turbofish (#(#args),*);
            }
            #all #turbofish (#(#args),*)
        }

        #[cfg_attr(
            not(feature = "no-avx512"),
            multiversion::multiversion(targets(#wide, #narrow))
        )]
        #[cfg_attr(feature = "no-avx512", multiversion::multiversion(targets(#narrow)))]
        #(#others)*
        #all_sig #block

        #[cfg(not(feature = "no-avx512"))]
        #[multiversion::multiversion(targets(#narrow))]
        #(#others)*
        #avx2_sig #block
    })
}
